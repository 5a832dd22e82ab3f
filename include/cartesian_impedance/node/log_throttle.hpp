#pragma once
/// @file
/// How a node logs rejected input without flooding its log: one line per kind of mistake and
/// interval, with the count of those not shown. The kind is the topic plus the rejected field and
/// the fault's reason (Error::fault(): "dq" and "is above plausibility.joint_velocity"), so that a
/// different mistake is reported at once while a flood of the same one, whatever its values,
/// gives one line per interval; an error without a fault shares its topic's key. Memory is
/// bounded: at most max_keys keys plus one for everything beyond them. No ROS types; not
/// thread-safe (one per thread that logs).

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::node {

/// A peer's text (a frame_id, a name) as a log line or a reply names it: quoted as given if it has
/// at most `shown` characters, else its first `shown` and its length ("'abc...' (8388608
/// characters)"); control characters shown as '?', so that a newline in it cannot start a forged
/// log line. A frame_id of megabytes would otherwise make a log line of megabytes.
std::string quoted(std::string_view text, std::size_t shown = 64);

class LogThrottle {
 public:
  using Clock = std::chrono::steady_clock;

  /// `interval`: the shortest time between two lines of one key; `max_keys`: how many keys are
  /// kept (at least 1).
  explicit LogThrottle(Clock::duration interval = std::chrono::seconds(1),
                       std::size_t max_keys = 256);

  /// The line to log for `text`, a rejection on `topic` whose fault is `fault` (empty for none),
  /// at `now`: `text`, with " (and N more like it since the last report)" if N were held back;
  /// nothing if a line of the same key was logged less than an interval ago (then it is counted).
  std::optional<std::string> line(std::string_view topic, const Fault& fault, std::string_view text,
                                  Clock::time_point now = Clock::now());

  /// line() for an exception that rejected a message of `topic`: "<topic> rejected: <what()>",
  /// keyed by its fault if it is an Error.
  std::optional<std::string> rejected(std::string_view topic, const std::exception& error,
                                      Clock::time_point now = Clock::now());

  /// The keys kept, not counting the one beyond max_keys.
  std::size_t keys() const { return entries_.size(); }

 private:
  struct Entry {
    Clock::time_point last{};  // when its last line was logged
    bool logged = false;       // a line was logged at all
    std::uint64_t held_back = 0;
  };
  Entry& entry(const std::string& key, Clock::time_point now);

  Clock::duration interval_;
  std::size_t max_keys_;
  std::map<std::string, Entry, std::less<>> entries_;
  Entry beyond_;  // every key that found no room
};

}  // namespace cartesian_impedance::node
