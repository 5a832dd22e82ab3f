#pragma once
/// @file
/// Lock-free hand-off between the control cycle and other threads, with no allocation after
/// construction:
/// - CommandQueue: many writers, one reader (the cycle). A command is copied in whole before it
///   is published, so the reader never sees a torn command; a full queue makes push() return
///   false instead of blocking.
/// - SnapshotBuffer: one writer (the cycle), any number of readers, each reading the latest
///   complete snapshot. The writer never waits; a reader retries only while the writer publishes.

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <utility>

namespace cartesian_impedance {

/// Bounded multi-producer single-consumer queue (D. Vyukov's bounded MPMC queue, used with one
/// consumer). Each cell carries a sequence number that tells producers and the consumer whose turn
/// it is, so publication is a single release store after the payload is written.
template <typename T>
class CommandQueue {
 public:
  /// `capacity` is rounded up to a power of two (at least 2).
  explicit CommandQueue(std::size_t capacity) {
    std::size_t size = 2;
    while (size < capacity) size *= 2;
    mask_ = size - 1;
    cells_ = std::make_unique<Cell[]>(size);
    for (std::size_t i = 0; i < size; ++i) cells_[i].sequence.store(i, std::memory_order_relaxed);
  }

  CommandQueue(const CommandQueue&) = delete;
  CommandQueue& operator=(const CommandQueue&) = delete;

  std::size_t capacity() const noexcept { return mask_ + 1; }

  /// Copies `value` in; false if the queue is full. Safe from any number of threads at once.
  bool push(const T& value) noexcept(std::is_nothrow_copy_assignable_v<T>) {
    std::size_t position = enqueue_.load(std::memory_order_relaxed);
    for (;;) {
      Cell& cell = cells_[position & mask_];
      const std::size_t sequence = cell.sequence.load(std::memory_order_acquire);
      const auto difference =
          static_cast<std::ptrdiff_t>(sequence) - static_cast<std::ptrdiff_t>(position);
      if (difference == 0) {
        if (enqueue_.compare_exchange_weak(position, position + 1, std::memory_order_relaxed)) {
          cell.value = value;
          cell.sequence.store(position + 1, std::memory_order_release);
          return true;
        }
      } else if (difference < 0) {
        return false;  // full
      } else {
        position = enqueue_.load(std::memory_order_relaxed);
      }
    }
  }

  /// Copies the oldest command out; false if there is none. Only one thread may pop.
  bool pop(T& value) noexcept(std::is_nothrow_copy_assignable_v<T>) {
    Cell& cell = cells_[dequeue_ & mask_];
    const std::size_t sequence = cell.sequence.load(std::memory_order_acquire);
    if (sequence != dequeue_ + 1) return false;
    value = cell.value;
    cell.sequence.store(dequeue_ + mask_ + 1, std::memory_order_release);
    ++dequeue_;
    return true;
  }

 private:
  struct Cell {
    std::atomic<std::size_t> sequence{0};
    T value{};
  };

  std::unique_ptr<Cell[]> cells_;
  std::size_t mask_ = 0;
  alignas(64) std::atomic<std::size_t> enqueue_{0};
  alignas(64) std::size_t dequeue_ = 0;
};

/// Latest-value buffer: one writer publishes snapshots, any number of readers copy the newest.
/// Readers announce themselves on a slot before copying it and re-check that it is still the
/// newest; the writer only writes slots that are neither the newest nor being read, so a reader
/// never sees a half-written snapshot. With kSlots slots, kSlots - 2 readers can hold old slots
/// before a publication is skipped (the next one then goes through).
template <typename T, int kSlots = 8>
class SnapshotBuffer {
  static_assert(kSlots >= 3, "one slot to read, one to write, one spare");

 public:
  SnapshotBuffer() = default;
  explicit SnapshotBuffer(const T& initial) {
    for (auto& slot : slots_) slot.value = initial;
  }

  /// Makes a copy of `value` the newest snapshot. Never blocks. Returns false if every other slot
  /// was being read (the snapshot is then dropped). Only one thread may publish.
  bool publish(const T& value) noexcept(std::is_nothrow_copy_assignable_v<T>) {
    return publish_with([&value](T& slot) { slot = value; }) != nullptr;
  }

  /// Like publish(), but `write(T&)` fills the free slot in place (it may assume nothing of the
  /// slot's old contents beyond its being a valid T). Returns the new snapshot, which stays
  /// unchanged until the publishing thread publishes again, or nullptr if every other slot was
  /// being read (nothing is then written).
  template <typename Write>
  const T* publish_with(Write&& write) noexcept(noexcept(write(std::declval<T&>()))) {
    const int newest = newest_.load(std::memory_order_seq_cst);
    for (int i = 1; i < kSlots; ++i) {
      const int slot = (newest + i) % kSlots;
      if (slots_[slot].readers.load(std::memory_order_seq_cst) != 0) continue;
      write(slots_[slot].value);
      newest_.store(slot, std::memory_order_seq_cst);
      // A reader that announced itself on `slot` after the check above sees `newest_` move
      // away from it only later; readers re-check `newest_` after announcing, so they retry.
      return &slots_[slot].value;
    }
    return nullptr;
  }

  /// Copies the newest snapshot into `value`. Safe from any number of threads at once.
  void read(T& value) const noexcept(std::is_nothrow_copy_assignable_v<T>) {
    for (;;) {
      const int slot = newest_.load(std::memory_order_seq_cst);
      slots_[slot].readers.fetch_add(1, std::memory_order_seq_cst);
      if (newest_.load(std::memory_order_seq_cst) == slot) {
        value = slots_[slot].value;
        slots_[slot].readers.fetch_sub(1, std::memory_order_seq_cst);
        return;
      }
      slots_[slot].readers.fetch_sub(1, std::memory_order_seq_cst);
    }
  }

  T read() const {
    T value;
    read(value);
    return value;
  }

 private:
  struct Slot {
    mutable std::atomic<int> readers{0};
    T value{};
  };

  Slot slots_[kSlots];
  std::atomic<int> newest_{0};
};

}  // namespace cartesian_impedance
