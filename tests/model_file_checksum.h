#ifndef STRUCTGP_TESTS_MODEL_FILE_CHECKSUM_H_
#define STRUCTGP_TESTS_MODEL_FILE_CHECKSUM_H_

// The checksum of a model file as the format defines it (docs/reliability.md), written
// independently of the loader: CRC-32 of the compact JSON text of the object without its
// "checksum" field, as "crc32:xxxxxxxx". For tests and the fuzz target, which edit a model
// file's JSON and must give it a valid checksum so that the loader's deeper checks are reached.

#include <zlib.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

namespace structgp {
namespace testing {

// Replaces doc's "checksum" field (doc must be a JSON object) by the one its contents give.
inline void SetValidChecksum(nlohmann::json* doc) {
  doc->erase("checksum");
  const std::string compact = doc->dump();
  const uLong crc = crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(compact.data()),
                          static_cast<uInt>(compact.size()));
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "crc32:%08lx", static_cast<unsigned long>(crc));
  (*doc)["checksum"] = buffer;
}

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTS_MODEL_FILE_CHECKSUM_H_
