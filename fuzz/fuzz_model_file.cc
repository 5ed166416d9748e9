// libFuzzer target: the model file loader (io/model_file.h). Each input is parsed as it is and,
// when it is a JSON object, once more with its checksum recomputed, so that mutations reach
// the checks behind the checksum (sizes, invariants, payload decoding); the header reader
// (ParseModelFileHeader) on the same input. A DataError is the expected outcome for a bad file; a model that loads must predict (or return a status, never a
// NaN) and save again.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>

#include "structgp/core/types.h"
#include "model_file_checksum.h"
#include "structgp/io/model_file.h"

namespace {

void Check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "fuzz_model_file: broken guarantee: %s\n", what);
    std::abort();
  }
}

void LoadAndCheck(const std::string& text) {
  // The header reader shares the checks of what it reads: it refuses a file with a DataError
  // or reads it, and a file that loads has a header that agrees with the model.
  bool header_read = false;
  structgp::ModelFileHeader header;
  try {
    header = structgp::ParseModelFileHeader(text, "fuzz.json");
    header_read = true;
  } catch (const structgp::DataError& e) {
    Check(e.file() == "fuzz.json", "DataError names the file (header)");
  }
  try {
    const structgp::RobotModel model = structgp::ParseModelFile(text, "fuzz.json");
    Check(model.fitted(), "a loaded model is fitted");
    const int n = model.num_joints();
    Check(header_read && header.num_joints == n && header.form == model.gp().form(),
          "a file that loads has a header that agrees with it");
    structgp::Vector x = structgp::Vector::Zero(model.input_dim());
    structgp::Vector mean(n), latent(n), noisy(n);
    // Weights of absurd (finite) magnitude may overflow a prediction: then a status says so.
    const structgp::Status status = model.PredictWithVariance(x, mean, latent, noisy);
    Check(status == structgp::Status::kOk || status == structgp::Status::kInvalidInput,
          "a loaded model predicts at x = 0 or says why not");
    if (status == structgp::Status::kOk) {
      Check(mean.allFinite() && latent.allFinite() && noisy.allFinite(), "finite prediction");
      Check((latent.array() >= 0.0).all(), "variance not negative");
    }
    // Saving it again gives a file that loads again.
    const structgp::RobotModel again =
        structgp::ParseModelFile(structgp::ModelFileText(model), "again.json");
    Check(again.num_joints() == n, "the saved model loads again");
  } catch (const structgp::DataError& e) {
    Check(e.file() == "fuzz.json", "DataError names the file");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* bytes, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(bytes), size);
  LoadAndCheck(text);
  nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_object()) {
    structgp::testing::SetValidChecksum(&doc);
    LoadAndCheck(doc.dump());
  }
  return 0;
}
