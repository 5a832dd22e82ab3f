// The node layer's log throttle (node/log_throttle.hpp): one line per kind of mistake and
// interval, the count of those held back, a different mistake at once, bounded memory. Time is
// given, not measured: every case is exact.

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/node/log_throttle.hpp"

namespace ci = cartesian_impedance;
using ci::node::LogThrottle;

namespace {

const LogThrottle::Clock::time_point kStart{};

LogThrottle::Clock::time_point at_ms(long milliseconds) {
  return kStart + std::chrono::milliseconds(milliseconds);
}

// A fault of one input and reason; index and value vary between reports of one kind.
ci::Fault fault(const char* input, const char* reason, int index = 0, double value = 0.0) {
  ci::Fault f;
  f.input = input;
  f.reason = reason;
  f.index = index;
  f.value = value;
  return f;
}

}  // namespace

TEST(LogThrottle, DistinctMessagesWithoutAFieldAreOneKeyAndOneLinePerSecondPerTopic) {
  LogThrottle throttle;  // 1 s
  std::vector<std::string> lines;
  // 1,000 messages per second on each of two topics for 3 s, every text different.
  for (long ms = 0; ms < 3000; ++ms) {
    for (const char* topic : {"set_config", "joint_trajectory"}) {
      const std::runtime_error error("message " + std::to_string(ms) + " is wrong");
      if (auto line = throttle.rejected(topic, error, at_ms(ms))) lines.push_back(*line);
    }
  }
  EXPECT_EQ(throttle.keys(), 2u);
  // At 0, 1000 and 2000 ms on each topic; the later ones count the 999 held back.
  ASSERT_EQ(lines.size(), 6u);
  EXPECT_EQ(lines[0], "set_config rejected: message 0 is wrong");
  EXPECT_EQ(lines[1], "joint_trajectory rejected: message 0 is wrong");
  EXPECT_EQ(lines[2],
            "set_config rejected: message 1000 is wrong (and 999 more like it since the last "
            "report)");
  EXPECT_EQ(lines[5],
            "joint_trajectory rejected: message 2000 is wrong (and 999 more like it since the "
            "last report)");
}

TEST(LogThrottle, ADifferentFieldOrReasonIsReportedAtOnce) {
  LogThrottle throttle;
  const char* const fast = "is above plausibility.joint_velocity";
  const char* const not_finite = "is not finite";
  EXPECT_TRUE(throttle.line("joint_states", fault("dq", fast, 3, 50.0), "a", at_ms(0)));
  // The same kind on another joint or with another value: held back.
  EXPECT_FALSE(throttle.line("joint_states", fault("dq", fast, 4, 60.0), "b", at_ms(1)));
  // Another field, another reason, another topic, an error without a fault: at once.
  EXPECT_TRUE(throttle.line("joint_states", fault("q", fast), "c", at_ms(2)));
  EXPECT_TRUE(throttle.line("joint_states", fault("dq", not_finite), "d", at_ms(3)));
  EXPECT_TRUE(throttle.line("reference_pose", fault("dq", fast), "e", at_ms(4)));
  EXPECT_TRUE(throttle.line("joint_states", ci::Fault{}, "f", at_ms(5)));
  EXPECT_EQ(throttle.keys(), 5u);
  // An Error's fault is its key: the same field and reason as the first line.
  const ci::Error error(fault("dq", fast, 1, 11.0), "dq[1] = 11 rad/s is too fast");
  EXPECT_FALSE(throttle.rejected("joint_states", error, at_ms(6)));
  EXPECT_EQ(throttle.rejected("joint_states", error, at_ms(1000)),
            "joint_states rejected: dq[1] = 11 rad/s is too fast (and 2 more like it since the "
            "last report)");
}

TEST(LogThrottle, MemoryStaysBoundedAndQuietKeysMakeRoom) {
  LogThrottle throttle(std::chrono::seconds(1), 8);
  // 1,000 distinct fields within one second (a bug would be needed for this many: the fields are
  // the parameter table's and the commands'): 8 keys, then one shared key for the rest.
  std::vector<std::string> fields;
  for (int i = 0; i < 1000; ++i) fields.push_back("field" + std::to_string(i));
  int lines = 0;
  for (int i = 0; i < 1000; ++i) {
    if (throttle.line("set_config", fault(fields[i].c_str(), "is wrong"), "x", at_ms(i / 10))) {
      ++lines;
    }
    ASSERT_LE(throttle.keys(), 8u);
  }
  EXPECT_EQ(lines, 8 + 1);
  // A second later the keys are quiet (nothing held back): new fields take their place and are
  // reported at once.
  lines = 0;
  for (int i = 0; i < 8; ++i) {
    if (throttle.line("set_config", fault(fields[i + 500].c_str(), "is wrong"), "y", at_ms(1200))) {
      ++lines;
    }
  }
  EXPECT_EQ(lines, 8);
  EXPECT_EQ(throttle.keys(), 8u);
}
