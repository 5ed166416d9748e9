#ifndef STRUCTGP_CORE_VERSION_H_
#define STRUCTGP_CORE_VERSION_H_

/// @file
/// The version of the library: the CMake project version it was built as ("0.1.0"), the same
/// text `structgp --version` prints and the Python module's `__version__`.

namespace structgp {

/// "MAJOR.MINOR.PATCH" of the build (CMake's PROJECT_VERSION).
const char* Version();

}  // namespace structgp

#endif  // STRUCTGP_CORE_VERSION_H_
