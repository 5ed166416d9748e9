// The include order of the library's areas (cmake/layers.txt): no file includes a header of
// an area listed after its own. Checked on the project's tree, and shown to fail on a tree
// with a back edge.

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "temp_files.h"

namespace structgp {
namespace {

namespace fs = std::filesystem;

// Areas in order, from a layers file (one name per line, '#' comments).
std::vector<std::string> ReadLayers(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> layers;
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    line.erase(std::remove_if(line.begin(), line.end(), ::isspace), line.end());
    if (!line.empty()) layers.push_back(line);
  }
  return layers;
}

// The area a path under root belongs to ("" for files outside the areas: the umbrella header).
std::string AreaOf(const fs::path& root, const fs::path& file) {
  const fs::path rel = fs::relative(file, root);
  auto it = rel.begin();
  if (it == rel.end()) return "";
  const std::string top = (it++)->string();
  if (it == rel.end()) return "";
  if (top == "src") {
    const std::string area = it->string();
    return ++it == rel.end() ? "" : area;
  }
  if (top == "include" && (it++)->string() == "structgp" && it != rel.end()) {
    const std::string area = it->string();
    if (++it == rel.end()) return "";  // include/structgp/structgp.h
    return area;
  }
  return "";
}

// The quoted includes of a file: (line number, header as written).
std::vector<std::pair<int, std::string>> Includes(const fs::path& file) {
  static const std::regex include_line(R"re(^\s*#\s*include\s*"([^"]+)")re");
  std::vector<std::pair<int, std::string>> out;
  std::ifstream in(file);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    std::smatch match;
    if (std::regex_search(line, match, include_line)) out.emplace_back(number, match[1]);
  }
  return out;
}

class LayerCheck {
 public:
  explicit LayerCheck(const fs::path& root)
      : root_(root), layers_(ReadLayers(root / "cmake" / "layers.txt")) {}

  int Rank(const std::string& area) const {
    const auto it = std::find(layers_.begin(), layers_.end(), area);
    return it == layers_.end() ? -1 : static_cast<int>(it - layers_.begin());
  }

  // The area of a file. A header of include/structgp/internal/ (not API, used by several
  // areas) belongs to the latest area it includes, core when it includes none.
  std::string Area(const fs::path& file) const {
    const std::string area = AreaOf(root_, file);
    if (area != "internal") return area;
    std::string highest = layers_.empty() ? "core" : layers_.front();
    for (const auto& [line, header] : Includes(file)) {
      const std::string target = Target(file, header);
      if (!target.empty() && target != "internal" && Rank(target) > Rank(highest)) {
        highest = target;
      }
    }
    return highest;
  }

  // The area of the file an include names ("" outside the areas).
  std::string Target(const fs::path& from, const std::string& header) const {
    const fs::path path = header.rfind("structgp/", 0) == 0
                              ? root_ / "include" / header
                              : (from.parent_path() / header).lexically_normal();
    const std::string area = AreaOf(root_, path);
    return area == "internal" && fs::exists(path) ? Area(path) : area;
  }

  // Every include of a header of an area listed after the including file's area, as
  // "path:line: <area> includes <header> of area '<other>', listed after it"; files of an
  // area missing from cmake/layers.txt are reported too.
  std::vector<std::string> BackEdges() const {
    std::vector<std::string> problems;
    for (const char* top : {"include/structgp", "src"}) {
      if (!fs::exists(root_ / top)) continue;
      for (const auto& entry : fs::recursive_directory_iterator(root_ / top)) {
        if (!entry.is_regular_file()) continue;
        const std::string ext = entry.path().extension().string();
        if (ext != ".h" && ext != ".cc") continue;
        const std::string area = Area(entry.path());
        if (area.empty()) continue;
        const std::string where = fs::relative(entry.path(), root_).string();
        if (Rank(area) < 0) {
          problems.push_back(where + ": area '" + area + "' is not in cmake/layers.txt");
          continue;
        }
        for (const auto& [line, header] : Includes(entry.path())) {
          const std::string target = Target(entry.path(), header);
          if (target.empty() || target == area) continue;
          if (Rank(target) < 0 || Rank(target) > Rank(area)) {
            problems.push_back(where + ":" + std::to_string(line) + ": " + area + " includes " +
                               header + " of area '" + target + "', listed after it");
          }
        }
      }
    }
    std::sort(problems.begin(), problems.end());
    return problems;
  }

 private:
  fs::path root_;
  std::vector<std::string> layers_;
};

std::vector<std::string> BackEdges(const fs::path& root) { return LayerCheck(root).BackEdges(); }

std::string Join(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += l + "\n";
  return out;
}

TEST(Layers, NoIncludePointsToALaterArea) {
  const std::vector<std::string> problems = BackEdges(STRUCTGP_SOURCE_DIR);
  EXPECT_TRUE(problems.empty()) << Join(problems);
}

TEST(Layers, EveryAreaOfTheTreeIsListed) {
  const fs::path root = STRUCTGP_SOURCE_DIR;
  const std::vector<std::string> layers = ReadLayers(root / "cmake" / "layers.txt");
  ASSERT_FALSE(layers.empty());
  for (const auto& dir : {root / "src", root / "include" / "structgp"}) {
    for (const auto& entry : fs::directory_iterator(dir)) {
      if (!entry.is_directory()) continue;
      const std::string area = entry.path().filename().string();
      if (area == "internal") continue;
      EXPECT_NE(std::find(layers.begin(), layers.end(), area), layers.end())
          << entry.path() << " is not in cmake/layers.txt";
    }
  }
}

// The check fails on a tree with a back edge: feature including a kernel header.
TEST(Layers, ABackEdgeIsReported) {
  const testing::TempDir dir("layers");
  const fs::path root = dir.path();
  fs::create_directories(root / "cmake");
  fs::create_directories(root / "include" / "structgp" / "feature");
  fs::create_directories(root / "include" / "structgp" / "kernel");
  fs::create_directories(root / "src" / "feature");
  std::ofstream(root / "cmake" / "layers.txt") << "# order\ncore\nfeature\nkernel\n";
  std::ofstream(root / "include" / "structgp" / "kernel" / "kernel.h")
      << "#include \"structgp/feature/map.h\"\n";  // allowed: kernel after feature
  std::ofstream(root / "include" / "structgp" / "feature" / "map.h") << "// ok\n";
  std::ofstream(root / "src" / "feature" / "map.cc")
      << "#include \"structgp/feature/map.h\"\n\n#include \"structgp/kernel/kernel.h\"\n";
  const std::vector<std::string> problems = BackEdges(root);
  ASSERT_EQ(problems.size(), 1u) << Join(problems);
  EXPECT_EQ(problems[0],
            "src/feature/map.cc:3: feature includes structgp/kernel/kernel.h of area 'kernel', "
            "listed after it");
  // A relative include into another area is a back edge too; an unlisted area is reported.
  fs::create_directories(root / "src" / "extra");
  std::ofstream(root / "src" / "extra" / "x.cc") << "// x\n";
  std::ofstream(root / "src" / "feature" / "map.cc") << "#include \"../kernel/k.h\"\n";
  fs::create_directories(root / "src" / "kernel");
  std::ofstream(root / "src" / "kernel" / "k.h") << "// k\n";
  // An internal header that includes a kernel header belongs to kernel: feature may not use it.
  fs::create_directories(root / "include" / "structgp" / "internal");
  std::ofstream(root / "include" / "structgp" / "internal" / "gram.h")
      << "#include \"structgp/kernel/kernel.h\"\n";
  std::ofstream(root / "include" / "structgp" / "kernel" / "use.h")
      << "#include \"structgp/internal/gram.h\"\n";  // allowed
  std::ofstream(root / "include" / "structgp" / "feature" / "use.h")
      << "#include \"structgp/internal/gram.h\"\n";
  const std::vector<std::string> more = BackEdges(root);
  ASSERT_EQ(more.size(), 3u) << Join(more);
  EXPECT_EQ(more[0],
            "include/structgp/feature/use.h:1: feature includes structgp/internal/gram.h of area "
            "'kernel', listed after it");
  EXPECT_EQ(more[1], "src/extra/x.cc: area 'extra' is not in cmake/layers.txt");
  EXPECT_EQ(more[2],
            "src/feature/map.cc:1: feature includes ../kernel/k.h of area 'kernel', listed after "
            "it");
}

}  // namespace
}  // namespace structgp
