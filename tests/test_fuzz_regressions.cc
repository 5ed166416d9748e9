// Inputs found by the libFuzzer targets of fuzz/ (docs/reliability.md), kept in tests/data/fuzz/
// and replayed here with the same guarantees the targets check, so that a finding stays fixed.

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "model_file_checksum.h"
#include "structgp/io/data_error.h"
#include "structgp/io/model_file.h"

#ifndef STRUCTGP_TEST_DATA_DIR
#error "STRUCTGP_TEST_DATA_DIR must name tests/data"
#endif

namespace structgp {
namespace {

std::string ReadData(const std::string& name) {
  const std::string path = std::string(STRUCTGP_TEST_DATA_DIR) + "/fuzz/" + name;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The text with its checksum recomputed, as fuzz_model_file does before its second parse.
std::string WithValidChecksum(const std::string& text) {
  nlohmann::json doc = nlohmann::json::parse(text);
  testing::SetValidChecksum(&doc);
  return doc.dump();
}

// fuzz_model_file: one bit flipped in the exponent of an entry of the covariance factor S
// (-0.0328 became 5.9e306), with a matching checksum. The file loaded, and the variance of any
// prediction overflowed. Now the loader checks that no posterior variance exceeds the prior one
// (diag(S S^T) <= Lambda_e / sigma_n^2) and refuses the file.
TEST(FuzzRegression, ModelFileWithAHugeFactorEntryIsRefused) {
  const std::string text = WithValidChecksum(ReadData("model_file_factor_entry_1e306.json"));
  try {
    ParseModelFile(text, "found.json");
    FAIL() << "the damaged model file was accepted";
  } catch (const DataError& e) {
    EXPECT_EQ(e.file(), "found.json");
    EXPECT_NE(std::string(e.what()).find("posterior variance above the prior variance"),
              std::string::npos)
        << e.what();
  }
}

// fuzz_model_file: in a function-space model file (stored points, refitted on load) a copied
// chunk of base64 turned some targets into values near 1e300, with a matching checksum. The
// refit overflowed silently and every prediction was NaN with status kOk. Now KernelGP::Fit
// refuses weights that are not finite (and Add / Predict report overflow by status), so the
// loader refuses the file.
TEST(FuzzRegression, FunctionSpaceModelFileWithOverflowingTargetsIsRefused) {
  const std::string text =
      WithValidChecksum(ReadData("model_file_function_space_target_overflow.json"));
  try {
    ParseModelFile(text, "found.json");
    FAIL() << "the damaged model file was accepted";
  } catch (const DataError& e) {
    EXPECT_EQ(e.file(), "found.json");
    EXPECT_NE(std::string(e.what()).find("the stored points cannot be refitted"),
              std::string::npos)
        << e.what();
  }
}

// fuzz_model_file: a number too large for a double ('888888888888888888888888e88888') is valid
// JSON syntax, but the JSON parser throws out_of_range for it, not parse_error; it escaped
// ParseModelFile as a foreign exception (the program would have stopped with terminate). Now
// it is a DataError naming the file, the line and column of the number and the reason.
TEST(FuzzRegression, ModelFileWithANumberBeyondDoubleIsADataError) {
  const std::string text = ReadData("model_file_number_overflow.json");
  try {
    ParseModelFile(text, "found.json");
    FAIL() << "accepted";
  } catch (const DataError& e) {
    EXPECT_EQ(e.file(), "found.json");
    EXPECT_NE(std::string(e.what()).find("malformed model file (not valid JSON): number overflow"),
              std::string::npos)
        << e.what();
    EXPECT_GT(e.line(), 0) << e.what();
  }
  // The same with a number in an otherwise valid model file.
  try {
    ParseModelFile("{\"format\": \"structgp-model\", \"version\": 1e999}", "small.json");
    FAIL() << "accepted";
  } catch (const DataError& e) {
    EXPECT_EQ(std::string(e.what()),
              "small.json:1:41: malformed model file (not valid JSON): number overflow parsing "
              "'1e999'");
  }
}

// fuzz_model_file: a model whose feature map has no shape parameter, used as a kernel, made
// PriorVariance scale blocks of an empty Jacobian (no storage): Eigen offset a null pointer,
// undefined behaviour reported by UBSan. The file must load or be refused cleanly; the
// sanitizer build of this test is what proves the fix.
TEST(FuzzRegression, KernelModelWithoutShapeParametersLoadsCleanly) {
  for (const bool fix_checksum : {false, true}) {
    const std::string raw = ReadData("model_file_kernel_prior_empty_jacobian.json");
    const std::string text = fix_checksum ? WithValidChecksum(raw) : raw;
    try {
      const RobotModel model = ParseModelFile(text, "found.json");
      EXPECT_TRUE(model.fitted());
    } catch (const DataError& e) {
      EXPECT_EQ(e.file(), "found.json");
    }
  }
}

}  // namespace
}  // namespace structgp
