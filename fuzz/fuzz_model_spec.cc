// libFuzzer target: the model and effect spec parsers (model/model_spec.h). Bad text must give
// std::invalid_argument; accepted text must round-trip through ToString.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "structgp/model/model_spec.h"

namespace {

void Check(bool condition, const char* what, const std::string& text) {
  if (!condition) {
    std::fprintf(stderr, "fuzz_model_spec: broken guarantee: %s (text '%s')\n", what,
                 text.c_str());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* bytes, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(bytes), size);

  try {
    const structgp::ModelSpec spec = structgp::ParseModelSpec(text);
    const std::string canonical = structgp::ToString(spec);
    Check(structgp::ToString(structgp::ParseModelSpec(canonical)) == canonical,
          "model spec round trip", text);
  } catch (const std::invalid_argument&) {
  }

  try {
    const std::vector<structgp::EffectSpec> effects = structgp::ParseEffectList(text);
    const std::string canonical = structgp::ToString(effects);
    Check(structgp::ToString(structgp::ParseEffectList(canonical)) == canonical,
          "effect list round trip", text);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
