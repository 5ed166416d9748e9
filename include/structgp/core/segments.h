#ifndef STRUCTGP_CORE_SEGMENTS_H_
#define STRUCTGP_CORE_SEGMENTS_H_

/// @file
/// The trajectories (segments) of a log, and contiguous folds that respect them.
///
/// A log may hold several trajectories one after the other, each with its time starting again
/// (published multi-trajectory data sets are written so): a segment is a run of rows whose time
/// never decreases, and a new one starts at every row whose time is below the previous row's.
/// Cross-validation and the diagnosis hold out whole segments when there are enough of them,
/// so that a held-out block is never a continuation of a training block across a restart.

#include <utility>
#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// First row of each segment of a log with times t: 0, then every i with t[i] < t[i - 1].
/// {0} for an empty t (a log without times is one segment) and for m = 0.
std::vector<int> SegmentStarts(const ConstVectorRef& t);

/// k contiguous folds of rows 0..m-1, as half-open ranges [begin, end) in increasing order:
/// fold f is [floor(f m / k), floor((f + 1) m / k)). They cover every row exactly once and
/// their sizes differ by at most one. Throws std::invalid_argument unless 1 <= k <= m.
std::vector<std::pair<int, int>> ContiguousFolds(int m, int k);

/// k contiguous folds that respect segments: with at least k segments (segment_starts from
/// SegmentStarts), every fold is a run of whole segments, its boundaries the segment starts
/// nearest to ContiguousFolds' (each fold keeps at least one segment); with fewer, the plain
/// ContiguousFolds(m, k). Throws std::invalid_argument unless 1 <= k <= m and segment_starts is
/// increasing, starts at 0 and lies in [0, m).
std::vector<std::pair<int, int>> SegmentFolds(int m, int k, const std::vector<int>& segment_starts);

}  // namespace structgp

#endif  // STRUCTGP_CORE_SEGMENTS_H_
