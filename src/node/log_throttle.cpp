#include "cartesian_impedance/node/log_throttle.hpp"

#include <algorithm>
#include <utility>

namespace cartesian_impedance::node {

std::string quoted(std::string_view text, std::size_t shown) {
  std::string out = "'";
  for (std::size_t i = 0; i < text.size() && i < shown; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    out += (c < 0x20 || c == 0x7f) ? '?' : text[i];
  }
  out += text.size() > shown ? "...' (" + std::to_string(text.size()) + " characters)" : "'";
  return out;
}

LogThrottle::LogThrottle(Clock::duration interval, std::size_t max_keys)
    : interval_(interval), max_keys_(std::max<std::size_t>(1, max_keys)) {}

LogThrottle::Entry& LogThrottle::entry(const std::string& key, Clock::time_point now) {
  const auto found = entries_.find(key);
  if (found != entries_.end()) return found->second;
  if (entries_.size() >= max_keys_) {
    // Forget keys quiet for an interval with nothing held back: their next line would be logged
    // at once anyway, so only memory changes.
    for (auto it = entries_.begin(); it != entries_.end();) {
      const bool quiet = it->second.held_back == 0 && now - it->second.last >= interval_;
      it = quiet ? entries_.erase(it) : std::next(it);
    }
    if (entries_.size() >= max_keys_) return beyond_;
  }
  return entries_[key];
}

std::optional<std::string> LogThrottle::line(std::string_view topic, const Fault& fault,
                                             std::string_view text, Clock::time_point now) {
  // The field and the reason name the kind of mistake; the index and value do not, so that a
  // flood of one mistake on many joints or with many values is one key.
  std::string key(topic);
  if (fault) {
    key.append("\n").append(fault.input).append("\n").append(fault.reason);
  }
  Entry& throttle = entry(key, now);
  if (throttle.logged && now - throttle.last < interval_) {
    ++throttle.held_back;
    return std::nullopt;
  }
  std::string result(text);
  if (throttle.held_back > 0) {
    result +=
        " (and " + std::to_string(throttle.held_back) + " more like it since the last report)";
  }
  throttle.last = now;
  throttle.logged = true;
  throttle.held_back = 0;
  return result;
}

std::optional<std::string> LogThrottle::rejected(std::string_view topic,
                                                 const std::exception& error,
                                                 Clock::time_point now) {
  const auto* library_error = dynamic_cast<const Error*>(&error);
  const std::string text = std::string(topic) + " rejected: " + error.what();
  return line(topic, library_error != nullptr ? library_error->fault() : Fault{}, text, now);
}

}  // namespace cartesian_impedance::node
