#include "cartesian_impedance/runtime/timing.hpp"

#include <algorithm>
#include <cmath>

namespace cartesian_impedance::runtime {

namespace {

constexpr auto relaxed = std::memory_order_relaxed;
constexpr std::int64_t kSubBins = std::int64_t{1} << DurationHistogram::kSubBinBits;
static_assert(DurationHistogram::kLinearBins == kSubBins,
              "the first power of two above the linear bins starts where they end");

}  // namespace

namespace {

// The bin whose value is the largest not above `ns` (0 <= ns < 2^20 us).
std::size_t bin_below(std::int64_t ns) noexcept {
  const auto us = static_cast<std::uint64_t>(ns / 1000);
  if (us < static_cast<std::uint64_t>(DurationHistogram::kLinearBins)) {
    return static_cast<std::size_t>(us);
  }
  const int octave = 63 - __builtin_clzll(us);  // us in [2^octave, 2^(octave + 1)), octave >= 7
  const int shift = octave - DurationHistogram::kSubBinBits;  // values 2^shift us apart
  return static_cast<std::size_t>(DurationHistogram::kLinearBins +
                                  (std::int64_t{shift} << DurationHistogram::kSubBinBits) +
                                  static_cast<std::int64_t>(us >> shift) - kSubBins);
}

}  // namespace

std::int64_t DurationHistogram::value_ns(std::size_t bin) noexcept {
  if (bin >= kBins) return kEndNs;
  const auto index = static_cast<std::int64_t>(bin);
  if (index < kLinearBins) return index * 1000;
  const std::int64_t above = index - kLinearBins;
  const auto shift = static_cast<int>(above >> kSubBinBits);
  return ((kSubBins + (above & (kSubBins - 1))) << shift) * 1000;
}

std::int64_t DurationHistogram::lower_ns(std::size_t bin) noexcept {
  if (bin == 0) return 0;
  const std::size_t last = std::min(bin, kBins);
  return (value_ns(last - 1) + value_ns(last)) / 2;  // whole: the values are whole microseconds
}

std::size_t DurationHistogram::bin_of(std::int64_t ns) noexcept {
  if (ns <= 0) return 0;
  if (ns >= kRangeNs) return kBins;
  // The nearest value; halfway rounds up.
  const std::size_t below = bin_below(ns);
  return ns - value_ns(below) >= value_ns(below + 1) - ns ? below + 1 : below;
}

void DurationHistogram::record(std::int64_t ns) noexcept {
  ns = std::max<std::int64_t>(ns, 0);
  // One writer: a load and a store instead of a read-modify-write.
  std::atomic<std::uint64_t>& bin = bins_[bin_of(ns)];
  bin.store(bin.load(relaxed) + 1, relaxed);
  if (ns < min_ns_.load(relaxed)) min_ns_.store(ns, relaxed);
  if (ns > max_ns_.load(relaxed)) max_ns_.store(ns, relaxed);
}

void DurationHistogram::reset() noexcept {
  for (std::atomic<std::uint64_t>& bin : bins_) bin.store(0, relaxed);
  min_ns_.store(std::numeric_limits<std::int64_t>::max(), relaxed);
  max_ns_.store(0, relaxed);
}

DurationHistogram::Snapshot DurationHistogram::snapshot() const noexcept {
  Snapshot snapshot;
  std::size_t lowest = kBins + 1;
  std::size_t highest = 0;
  for (std::size_t bin = 0; bin <= kBins; ++bin) {
    snapshot.bins[bin] = bins_[bin].load(relaxed);
    snapshot.count += snapshot.bins[bin];
    if (snapshot.bins[bin] != 0) {
      lowest = std::min(lowest, bin);
      highest = bin;
    }
  }
  if (snapshot.count == 0) return snapshot;
  // Keep the extremes consistent with the bins even if a duration being recorded is in one and
  // not yet in the other.
  const std::int64_t lowest_end =
      lowest < kBins ? lower_ns(lowest + 1) : std::numeric_limits<std::int64_t>::max();
  snapshot.min_ns = std::min(min_ns_.load(relaxed), lowest_end);
  snapshot.max_ns = std::max({max_ns_.load(relaxed), lower_ns(highest), snapshot.min_ns});
  return snapshot;
}

double DurationHistogram::Snapshot::quantile_us(double q) const noexcept {
  if (count == 0) return 0.0;
  const double clamped = std::isnan(q) ? 0.0 : std::clamp(q, 0.0, 1.0);
  const auto rank = std::clamp<std::uint64_t>(
      static_cast<std::uint64_t>(std::ceil(clamped * static_cast<double>(count))), 1, count);
  if (rank == 1) return min_us();  // the extremes are kept exactly
  if (rank == count) return max_us();
  std::uint64_t below = 0;
  std::size_t bin = 0;
  while (bin < kBins && below + bins[bin] < rank) below += bins[bin++];
  if (bin == kBins) return max_us();
  return 1e-3 * static_cast<double>(std::min(std::max(value_ns(bin), min_ns), max_ns));
}

DurationHistogram::Snapshot DurationHistogram::Snapshot::since(
    const Snapshot& earlier) const noexcept {
  if (earlier.count == 0) return *this;
  for (std::size_t bin = 0; bin <= kBins; ++bin) {
    if (bins[bin] < earlier.bins[bin]) return *this;  // reset in between
  }
  Snapshot window;
  std::size_t lowest = kBins + 1;
  std::size_t highest = 0;
  for (std::size_t bin = 0; bin <= kBins; ++bin) {
    window.bins[bin] = bins[bin] - earlier.bins[bin];
    window.count += window.bins[bin];
    if (window.bins[bin] != 0) {
      lowest = std::min(lowest, bin);
      highest = bin;
    }
  }
  if (window.count == 0) return window;
  // A new extreme was set in the window: exact. Otherwise the window's extreme lies in its
  // lowest (highest) bin: bound it by that bin's edge.
  window.min_ns = min_ns < earlier.min_ns ? min_ns : std::max(min_ns, lower_ns(lowest));
  window.max_ns = max_ns > earlier.max_ns || highest == kBins
                      ? max_ns
                      : std::min(max_ns, lower_ns(highest + 1));
  return window;
}

}  // namespace cartesian_impedance::runtime
