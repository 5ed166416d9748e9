// libFuzzer target: the robot data CSV reader (io/csv.h). The input bytes are written to a file
// (plain or gzip, as the reader decides from the content) and read with two sets of options.
// A DataError is the expected outcome for a bad file; any other exception, a crash, a
// sanitizer report or a result that breaks the documented guarantees is a finding.

#include <algorithm>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>

#include "structgp/io/csv.h"

namespace {

// A file of this process in the temporary directory, rewritten for every input.
const std::string& ScratchPath() {
  static const std::string path = [] {
    const char* dir = std::getenv("TMPDIR");
    return std::string(dir != nullptr && *dir != '\0' ? dir : "/tmp") + "/structgp_fuzz_csv_" +
           std::to_string(::getpid()) + ".csv";
  }();
  return path;
}

void Check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "fuzz_csv: broken guarantee: %s\n", what);
    std::abort();
  }
}

void ReadAndCheck(const structgp::CsvOptions& options) {
  structgp::RobotData data;
  try {
    data = structgp::ReadRobotCsv(ScratchPath(), options);
  } catch (const structgp::DataError& e) {
    Check(e.file() == ScratchPath(), "DataError names the file");
    Check(e.line() >= 0 && e.column() >= 0, "line and column are not negative");
    return;
  }
  const int n = data.num_joints;
  const long m = data.X.rows();
  Check(n >= 1, "at least one joint");
  Check(data.X.cols() == 3 * n && data.Y.cols() == n && data.Y.rows() == m, "X is m x 3N, Y m x N");
  Check(data.t.size() == 0 || data.t.size() == m, "t has m entries or none");
  Check(data.line.size() == m, "one line number per row");
  // t is non-decreasing within each trajectory: the segments start where it decreases.
  const std::vector<int> starts = data.segments();
  Check(!starts.empty() && starts.front() == 0, "the first trajectory starts at row 0");
  for (size_t s = 1; s < starts.size(); ++s) {
    Check(starts[s] > starts[s - 1] && starts[s] < m, "trajectory starts increase within the rows");
    Check(data.t[starts[s]] < data.t[starts[s] - 1], "a trajectory starts where t decreases");
  }
  for (long i = 1; i < data.t.size(); ++i) {
    const bool start = std::find(starts.begin(), starts.end(), static_cast<int>(i)) != starts.end();
    Check(start || data.t[i] >= data.t[i - 1], "t non-decreasing within a trajectory");
  }
  Check(data.t.allFinite(), "t finite");
  if (!options.allow_non_finite) {
    Check(data.X.allFinite() && data.Y.allFinite(), "values finite");
    Check(data.X.cwiseAbs().maxCoeff() <= options.max_abs || m == 0, "|X| <= max_abs");
    Check(data.Y.cwiseAbs().maxCoeff() <= options.max_abs || m == 0, "|Y| <= max_abs");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* bytes, std::size_t size) {
  std::FILE* file = std::fopen(ScratchPath().c_str(), "wb");
  if (file == nullptr) std::abort();
  if (size > 0 && std::fwrite(bytes, 1, size, file) != size) std::abort();
  std::fclose(file);

  ReadAndCheck(structgp::CsvOptions{});
  structgp::CsvOptions lax;
  lax.allow_non_finite = true;
  lax.max_abs = std::numeric_limits<double>::infinity();
  ReadAndCheck(lax);
  structgp::CsvOptions two_joints;
  two_joints.expected_joints = 2;
  ReadAndCheck(two_joints);
  return 0;
}
