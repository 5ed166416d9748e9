#ifndef STRUCTGP_ONLINE_TRIPLE_BUFFER_H_
#define STRUCTGP_ONLINE_TRIPLE_BUFFER_H_

/// @file
/// A wait-free single-writer, single-reader triple buffer: the writer publishes whole values
/// of T, the reader always sees the newest complete one, and neither ever waits for the other.
///
/// Three slots of T. At any time the writer owns one (its back slot), the reader owns one (its
/// front slot), and the third is the "middle" slot, parked in a shared atomic word together
/// with a "fresh" bit that says whether the middle holds a value the reader has not taken yet.
///
///     writer: fill back slot; Publish(): middle <-> back (exchange), fresh bit set
///     reader: Acquire(): if fresh, front <-> middle (exchange), fresh bit cleared; read front
///
/// Each side swaps its own slot with the middle by one atomic exchange, so each call is a
/// constant number of instructions (wait-free), and a slot is only ever touched by the side
/// that owns it.
///
/// Memory orders. Both exchanges are acq_rel:
/// - release on the writer's exchange makes the writes into the slot it hands over visible to
///   the reader that later receives that slot; acquire on the reader's exchange pairs with it;
/// - release on the reader's exchange orders the reader's last reads of the slot it hands back
///   before the writer, acquiring it with its next exchange, starts to overwrite that slot.
/// The reader's first look at the fresh bit (in Acquire) is a relaxed load: it only decides
/// whether to exchange at all; the exchange itself carries the acquire. A stale answer merely
/// delays the new value to the next Acquire.
///
/// Use: one writer thread calls write_buffer() and Publish(); one reader thread calls
/// Acquire() and read_buffer(). The slots are built once (copies of the initial value), so a
/// T whose copy assignment into an equally sized object does not allocate (Eigen matrices,
/// PODs) gives an allocation-free channel. The writer's back slot holds an older value (the
/// one the reader last gave back, or the initial one) and must be filled completely before
/// each Publish.

#include <atomic>
#include <cstdint>

namespace structgp {

template <typename T>
class TripleBuffer {
 public:
  /// All three slots start as copies of `initial`; the reader sees `initial` until the first
  /// Publish.
  explicit TripleBuffer(const T& initial) : slots_{Slot{initial}, Slot{initial}, Slot{initial}} {}

  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  // ---- writer side ---------------------------------------------------------------------------

  /// The writer's slot. Its content is an older value: overwrite all of it, then Publish().
  T& write_buffer() { return slots_[back_].value; }

  /// Makes the writer's slot the newest value and takes the middle slot as the new back slot.
  /// Wait-free: one atomic exchange. A value the reader has not acquired yet is replaced.
  void Publish() {
    const std::uint32_t previous = middle_.exchange(back_ | kFreshBit, std::memory_order_acq_rel);
    back_ = previous & kIndexMask;
  }

  // ---- reader side ---------------------------------------------------------------------------

  /// Takes the newest published value, if there is one the reader has not seen yet. Returns
  /// true when read_buffer() changed. Wait-free: at most one atomic exchange.
  bool Acquire() {
    if ((middle_.load(std::memory_order_relaxed) & kFreshBit) == 0) return false;
    const std::uint32_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = previous & kIndexMask;
    return true;
  }

  /// The reader's current value (the newest one as of the last Acquire).
  const T& read_buffer() const { return slots_[front_].value; }

 private:
  static constexpr std::uint32_t kFreshBit = 4;
  static constexpr std::uint32_t kIndexMask = 3;
  // Cache-line sized, so that the writer's and the reader's slots never share a line.
  static constexpr int kCacheLine = 64;

  struct alignas(kCacheLine) Slot {
    T value;
  };

  Slot slots_[3];
  // Invariant: {back_, front_, middle_ & kIndexMask} is always a permutation of {0, 1, 2}.
  alignas(kCacheLine) std::atomic<std::uint32_t> middle_{1};
  alignas(kCacheLine) std::uint32_t back_ = 0;   // writer only
  alignas(kCacheLine) std::uint32_t front_ = 2;  // reader only
};

}  // namespace structgp

#endif  // STRUCTGP_ONLINE_TRIPLE_BUFFER_H_
