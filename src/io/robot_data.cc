#include "structgp/io/robot_data.h"

#include "structgp/core/segments.h"

#include <stdexcept>
#include <string>

namespace structgp {

RobotData RobotData::Rows(int begin, int count) const {
  if (begin < 0 || count < 0 || begin > size() - count) {
    throw std::invalid_argument("RobotData::Rows: expected 0 <= begin, 0 <= count and begin + "
                                "count <= " + std::to_string(size()) + ", got begin = " +
                                std::to_string(begin) + ", count = " + std::to_string(count));
  }
  RobotData out;
  out.num_joints = num_joints;
  out.X = X.middleRows(begin, count);
  out.Y = Y.middleRows(begin, count);
  if (has_time()) out.t = t.segment(begin, count);
  out.source = source;
  out.target = target;
  if (line.size() == X.rows()) out.line = line.segment(begin, count);
  return out;
}

std::vector<int> RobotData::segments() const { return SegmentStarts(t); }

}  // namespace structgp
