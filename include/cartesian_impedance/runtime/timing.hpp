#pragma once
/// @file
/// A real-time-safe histogram of durations (the control thread's cycle periods and overrun
/// lateness): one thread records, any thread reads a snapshot and asks it for quantiles, for the
/// extremes or for what happened between two snapshots.
///
/// Bins: each bin stands for one value and counts the durations nearest to it. The values are
/// 0 to 255 us 1 us apart, then 128 per power of two (256 to 510 us 2 us apart, 512 to 1020 us
/// 4 us apart, ...), so a bin is never wider than max(1 us, 0.8 % of its durations), and a
/// duration is never further than max(0.5 us, 0.4 %) from its bin's value. Periods of 0.5, 1, 2, 4
/// and 8 ms are values of their own. The values reach 2^20 us (1.049 s); durations from
/// kRangeNs (1.047 s) on go to one overflow bin. The smallest and the largest duration are kept
/// exactly.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace cartesian_impedance::runtime {

class DurationHistogram {
 public:
  static constexpr std::int64_t kLinearBins = 128;  ///< values 0, 1, ..., 127 us
  static constexpr int kSubBinBits = 7;             ///< 2^7 bins per power of two above
  static constexpr int kOctaves = 13;               ///< values from 2^7 up to 2^20 us
  /// Bins below the range; the overflow bin (index kBins) holds everything from kRangeNs on.
  static constexpr std::size_t kBins =
      static_cast<std::size_t>(kLinearBins + (kOctaves << kSubBinBits));
  /// [ns] 2^20 us, where the values would go on after the last bin's (255 * 2^12 us)
  static constexpr std::int64_t kEndNs = (std::int64_t{1} << 20) * 1000;
  /// [ns] where the overflow bin begins: halfway between the last bin's value and kEndNs
  static constexpr std::int64_t kRangeNs = ((std::int64_t{255} << 12) * 1000 + kEndNs) / 2;

  /// The counts at one moment (snapshot()), or over a window (since()).
  struct Snapshot {
    std::array<std::uint64_t, kBins + 1> bins{};  ///< per bin; the last is the overflow bin
    std::uint64_t count = 0;                      ///< sum of bins
    /// [ns] the smallest and largest duration counted, 0 if none. Exact for a snapshot; for a
    /// window exact where the window set a new extreme, else a bound within one bin.
    std::int64_t min_ns = 0;
    std::int64_t max_ns = 0;

    /// [us] the q-quantile (q in [0, 1]: 0.5 the median, 0.99 the 99th percentile), of the
    /// ceil(q count)-th smallest duration: the value of its bin, clamped to [min, max], so within
    /// max(0.5 us, 0.4 %) of it; the minimum or the maximum if it is the smallest or the largest
    /// or in the overflow bin. 0 if nothing was counted.
    double quantile_us(double q) const noexcept;
    double min_us() const noexcept { return 1e-3 * static_cast<double>(min_ns); }
    double max_us() const noexcept { return 1e-3 * static_cast<double>(max_ns); }

    /// What was counted after `earlier` (a snapshot of the same histogram) up to this one. If the
    /// histogram was reset in between (a count went down), everything in this one.
    Snapshot since(const Snapshot& earlier) const noexcept;
  };

  /// Counts one duration [ns] (negative counts as 0). Real-time safe: no allocation, no lock,
  /// a few relaxed atomic loads and stores. One thread at a time.
  void record(std::int64_t ns) noexcept;

  /// Back to empty. Not concurrently with record().
  void reset() noexcept;

  /// The counts now, from any thread. Each bin is read atomically on its own, so a snapshot taken
  /// while a duration is recorded may or may not include it in the bin, the extremes or both.
  Snapshot snapshot() const noexcept;

  /// The bin of a duration [ns]: the one with the nearest value (halfway: the larger), kBins for
  /// the overflow bin.
  static std::size_t bin_of(std::int64_t ns) noexcept;
  /// [ns] the value bin `bin` stands for (< kBins); value_ns(kBins) = kEndNs.
  static std::int64_t value_ns(std::size_t bin) noexcept;
  /// [ns] the durations of bin `bin` are in [lower_ns(bin), lower_ns(bin + 1)); lower_ns(0) = 0,
  /// lower_ns(kBins) = kRangeNs.
  static std::int64_t lower_ns(std::size_t bin) noexcept;

 private:
  static_assert(std::atomic<std::uint64_t>::is_always_lock_free &&
                    std::atomic<std::int64_t>::is_always_lock_free,
                "the histogram must be lock-free to be recorded in a real-time thread");
  std::array<std::atomic<std::uint64_t>, kBins + 1> bins_{};
  std::atomic<std::int64_t> min_ns_{std::numeric_limits<std::int64_t>::max()};  // max: none yet
  std::atomic<std::int64_t> max_ns_{0};
};

}  // namespace cartesian_impedance::runtime
