#ifndef STRUCTGP_INTERNAL_TEXT_H_
#define STRUCTGP_INTERNAL_TEXT_H_

/// @file
/// Text helpers of the library's reports and of the structgp program (not API).

#include <string>
#include <vector>

namespace structgp {
namespace internal {

/// printf-style formatting into a string.
std::string Format(const char* format, ...) __attribute__((format(printf, 1, 2)));

/// "a", "a and b", "a, b and c".
std::string ListText(const std::vector<std::string>& items);

/// "1", "1 and 3", "1, 2 and 3": joints (1-based) as a person reads them.
std::string JointList(const std::vector<int>& joints);

/// "joint 1", "joints 1 and 3".
std::string JointsText(const std::vector<int>& joints);

/// The shortest decimal that reads back to the same double (std::to_chars), -0 as 0: numbers in
/// written documents (URDF) that must round-trip.
std::string ShortestDecimal(double value);

/// A table with aligned columns; rows[0] is the header. Columns of numbers are right-aligned;
/// the first column and columns of text left-aligned ("-" and "n/a" count as neither).
std::string Table(const std::vector<std::vector<std::string>>& rows, int indent = 2);

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_INTERNAL_TEXT_H_
