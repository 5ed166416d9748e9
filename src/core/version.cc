#include "structgp/core/version.h"

#ifndef STRUCTGP_VERSION_STRING
#error "STRUCTGP_VERSION_STRING must be the CMake project version (src/CMakeLists.txt)"
#endif

namespace structgp {

const char* Version() { return STRUCTGP_VERSION_STRING; }

}  // namespace structgp
