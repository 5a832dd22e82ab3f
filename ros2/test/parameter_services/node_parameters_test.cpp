// The node's parameters as the services show them, without DDS: rclcpp's list_parameters rules
// (prefixes, depth, the prefixes of the result), one parameter per row of the library's table
// and per node setting, types per ROS 2, and the sets refused before they reach the loop; on a
// running loop, sets as partial updates, the safety lock (issue 40) and the control period.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <optional>
#include <thread>

#include <cartesian_impedance/core/parameter_tree.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/model/robot_model.hpp>
#include <cartesian_impedance/node/startup_report.hpp>

#include "node_parameters.hpp"

namespace parameter_services_test {
namespace {

namespace ci = cartesian_impedance;
using cartesian_impedance_ros2::NamedValue;
using cartesian_impedance_ros2::NodeParameters;
using cartesian_impedance_ros2::RosValue;

class NodeParametersTest : public ::testing::Test {
 protected:
  NodeParametersTest()
      : model_(ci::RobotModel::from_urdf_file(
            std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
            "panda_link8")),
        loop_(model_, ci::Parameters{}) {
    settings_.base_link = "panda_link0";
    settings_.tip_link = "panda_link8";
    RosValue path;
    path.type = cartesian_impedance_ros2::ros_type::kString;
    path.text = "panda.urdf";
    parameters_.emplace(
        loop_, settings_, std::vector<NodeParameters::Extra>{{"urdf_path", path, "the URDF"}},
        [this] { return accepting_; }, "/arm");
  }

  ci::RobotModel model_;
  ci::ControlLoop loop_;
  ci::node::NodeSettings settings_;
  bool accepting_ = false;
  std::optional<NodeParameters> parameters_;
};

using Names = std::vector<std::string>;

TEST_F(NodeParametersTest, ListsEveryRowAndSettingInNameOrder) {
  const auto all = parameters_->list({}, 0);
  EXPECT_TRUE(std::is_sorted(all.names.begin(), all.names.end()));
  EXPECT_EQ(all.names.size(),
            ci::parameter_table().size() + ci::node::node_settings_table().size() + 1);
  // Depth 1 without prefixes: the names without a dot.
  const auto top = parameters_->list({}, 1);
  for (const std::string& name : top.names) EXPECT_EQ(name.find('.'), std::string::npos) << name;
  EXPECT_NE(std::find(top.names.begin(), top.names.end(), "control_rate"), top.names.end());
  EXPECT_TRUE(top.prefixes.empty());
}

TEST_F(NodeParametersTest, ListHonoursPrefixesAndDepthAsRclcpp) {
  // A prefix lists the names below it (prefix + '.'), depth counting the dots after it.
  EXPECT_EQ(parameters_->list({"limits.stiffness.translation"}, 0).names,
            (Names{"limits.stiffness.translation.max", "limits.stiffness.translation.min"}));
  EXPECT_EQ(parameters_->list({"limits.stiffness.translation"}, 0).prefixes,
            (Names{"limits.stiffness.translation"}));
  // rclcpp counts the dots of the name after the prefix, the one that follows the prefix
  // included: the children of "stiffness" are at depth 2, not 1.
  EXPECT_TRUE(parameters_->list({"stiffness"}, 1).names.empty());
  const auto stiffness = parameters_->list({"stiffness"}, 2);
  ASSERT_FALSE(stiffness.names.empty());
  for (const std::string& name : stiffness.names) {
    EXPECT_EQ(name.rfind("stiffness.", 0), 0u) << name;
    EXPECT_EQ(std::count(name.begin(), name.end(), '.'), 1) << name;
  }
  EXPECT_EQ(stiffness.prefixes, (Names{"stiffness"}));
  const auto limits = parameters_->list({"limits"}, 2);
  EXPECT_NE(std::find(limits.names.begin(), limits.names.end(), "limits.joint_torque"),
            limits.names.end());
  for (const std::string& name : limits.names) {
    EXPECT_EQ(std::count(name.begin(), name.end(), '.'), 1) << name;
  }
  // A name equal to a prefix is listed whatever the depth; a prefix is a whole name part.
  EXPECT_EQ(parameters_->list({"mode"}, 1).names, (Names{"mode"}));
  EXPECT_TRUE(parameters_->list({"mode"}, 1).prefixes.empty());
  EXPECT_TRUE(parameters_->list({"stiff"}, 0).names.empty());
  // Several prefixes: the union, in name order.
  const auto two = parameters_->list({"stiffness", "mode"}, 2);
  EXPECT_EQ(two.names.front(), "mode");
  EXPECT_EQ(two.names.size(), stiffness.names.size() + 1);
}

TEST_F(NodeParametersTest, ValuesAndDescriptorsCarryRos2Types) {
  const auto values =
      parameters_->get({"stiffness.translation", "stiffness.frame", "dynamics.gravity_compensation",
                        "realtime_priority", "mode", "start_q", "urdf_path"});
  ASSERT_TRUE(values);
  std::vector<std::uint8_t> types;
  for (const RosValue& v : *values) types.push_back(v.type);
  EXPECT_EQ(types, (std::vector<std::uint8_t>{8, 4, 1, 2, 4, 8, 4}));
  EXPECT_EQ((*values)[0].numbers.size(), 3u);
  EXPECT_EQ((*values)[4].text, "sim");
  EXPECT_EQ((*values)[6].text, "panda.urdf");
  EXPECT_FALSE(parameters_->get({"mode", "no.such.name"}));
  EXPECT_FALSE(parameters_->describe({"no.such.name"}));
  EXPECT_FALSE(parameters_->types({"stiffness"}));  // a group is no parameter

  const auto d = parameters_->describe({"stiffness.translation", "control_rate", "urdf_path"});
  ASSERT_TRUE(d && d->size() == 3u);
  const ci::ParameterInfo& row = ci::parameter_info("stiffness.translation");
  EXPECT_FALSE((*d)[0].read_only);
  EXPECT_NE((*d)[0].description.find(std::string(row.unit)), std::string::npos);
  EXPECT_EQ((*d)[0].floating_point_range, std::make_pair(row.min, row.max));
  EXPECT_TRUE((*d)[1].read_only);
  EXPECT_EQ((*d)[1].floating_point_range, std::make_pair(1.0, 10000.0));
  EXPECT_TRUE((*d)[2].read_only);
  // Every number of the table carries its range (all are finite; an infinite bound would be
  // stated in additional_constraints only) and the range's text.
  for (const ci::ParameterInfo& r : ci::parameter_table()) {
    const std::uint8_t type = cartesian_impedance_ros2::ros_type_of(r);
    if (type != 3 && type != 8) continue;
    const auto one = parameters_->describe({std::string(r.name)});
    ASSERT_TRUE(one && one->size() == 1u);
    EXPECT_EQ((*one)[0].floating_point_range, std::make_pair(r.min, r.max)) << r.name;
    EXPECT_NE((*one)[0].additional_constraints.find(r.range_text()), std::string::npos) << r.name;
  }
}

TEST_F(NodeParametersTest, SetsRefusedBeforeTheLoopChangeNothing) {
  const ci::Parameters before = loop_.latest_parameters();
  RosValue value;
  value.type = cartesian_impedance_ros2::ros_type::kDouble;
  value.number = 900.0;
  // Read-only, named.
  auto result = parameters_->set({{"control_rate", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("control_rate"), std::string::npos);
  EXPECT_NE(result.reason.find("read-only"), std::string::npos);
  // Not a ROS 2 type.
  RosValue odd = value;
  odd.type = 42;
  result = parameters_->set({{"stiffness.translation", odd}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("42"), std::string::npos) << result.reason;
  // The controller does not run yet: refused, whatever the value.
  result = parameters_->set({{"stiffness.translation", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("not running"), std::string::npos);
  // Once it runs, the decoder's messages: unknown name, value out of range, given twice.
  accepting_ = true;
  result = parameters_->set({{"stiffness.no_such", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("stiffness.no_such"), std::string::npos) << result.reason;
  value.number = -1.0;
  result = parameters_->set({{"stiffness.translation", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("parameter 'stiffness.translation' of /arm"), std::string::npos)
      << result.reason;
  value.number = 900.0;
  result = parameters_->set({{"stiffness.translation", value}, {"stiffness.translation", value}},
                            nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("twice"), std::string::npos) << result.reason;
  // Nothing reached the loop: a step applies whatever was queued, and the parameters are those
  // it started with.
  const ci::JointVector q =
      (ci::JointVector(7) << 0, -0.785, 0, -2.356, 0, 1.571, 0.785).finished();
  loop_.start(q, ci::JointVector::Zero(7));
  loop_.step(q, ci::JointVector::Zero(7), 0.001);
  EXPECT_EQ(loop_.latest_state().commands_applied, 0u);
  EXPECT_EQ(ci::encode_parameters(loop_.latest_parameters()), ci::encode_parameters(before));
  EXPECT_TRUE(parameters_->set({}, nullptr).successful);  // nothing to set: as rclcpp
}

// ---- on a running loop: partial updates, the safety lock, the control period ------------------

RosValue number(double v) {
  RosValue value;
  value.type = cartesian_impedance_ros2::ros_type::kDouble;
  value.number = v;
  return value;
}

RosValue flag(bool v) {
  RosValue value;
  value.type = cartesian_impedance_ros2::ros_type::kBool;
  value.boolean = v;
  return value;
}

// A loop with the shipped configuration's caps, stepped at about 1 kHz on a thread of its own
// as the node's control thread steps it (a set waits until the loop has applied it).
class RunningNodeParameters : public ::testing::Test {
 protected:
  void run(bool allow) {
    model_.emplace(ci::RobotModel::from_urdf_file(
        std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
        "panda_link8"));
    ci::Parameters capped;
    capped.safety.max_speed = {1.0, 2.5};
    capped.safety.max_force = {100.0, 20.0};
    capped.safety.workspace.stiffness = 2000.0;
    loop_.emplace(*model_, capped);
    if (allow) loop_->allow_runtime_safety_changes(true);
    settings_.base_link = "panda_link0";
    settings_.tip_link = "panda_link8";
    settings_.control_rate = 1000.0;
    settings_.allow_runtime_safety_changes = allow;
    parameters_.emplace(
        *loop_, settings_, std::vector<NodeParameters::Extra>{}, [] { return true; }, "/arm");
    loop_->start(ready(), ci::JointVector::Zero(7));
    stepping_ = std::thread([this] {
      while (!stop_) {
        loop_->step(ready(), ci::JointVector::Zero(7), 0.001);
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
  }
  ~RunningNodeParameters() override {
    stop_ = true;
    if (stepping_.joinable()) stepping_.join();
  }
  static ci::JointVector ready() {
    return (ci::JointVector(7) << 0, -0.785, 0, -2.356, 0, 1.571, 0.785).finished();
  }
  // Waits for two more steps, so that latest_state() and latest_parameters() show what the
  // commands sent before did.
  void settle() {
    const std::uint64_t cycle = loop_->latest_state().cycle;
    while (loop_->latest_state().cycle < cycle + 2) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

  std::optional<ci::RobotModel> model_;
  std::optional<ci::ControlLoop> loop_;
  ci::node::NodeSettings settings_;
  std::optional<NodeParameters> parameters_;
  std::atomic<bool> stop_{false};
  std::thread stepping_;
};

// Issue 40's measurement from a DDS peer: one set switched every cap off. Now, locked (the
// default), every safety setting is read-only in its descriptor, and a set that names one is
// refused whole, naming the setting, both values and the lock, whatever else it names.
TEST_F(RunningNodeParameters, SafetySettingsAreReadOnlyAndRefusedWhileLocked) {
  run(false);
  for (const ci::ParameterInfo& row : ci::parameter_table()) {
    const auto d = parameters_->describe({std::string(row.name)});
    ASSERT_TRUE(d && d->size() == 1u);
    EXPECT_EQ((*d)[0].read_only, ci::is_safety_setting(row.name)) << row.name;
    if (ci::is_safety_setting(row.name)) {
      EXPECT_NE((*d)[0].description.find("safety settings are locked"), std::string::npos)
          << (*d)[0].description;
      EXPECT_NE((*d)[0].description.find("allow_runtime_safety_changes: true"), std::string::npos)
          << (*d)[0].description;
    }
  }
  const auto setting = parameters_->get({"allow_runtime_safety_changes"});
  ASSERT_TRUE(setting && setting->size() == 1u);
  EXPECT_EQ((*setting)[0].type, cartesian_impedance_ros2::ros_type::kBool);
  EXPECT_FALSE((*setting)[0].boolean);

  const ci::Parameters before = loop_->latest_parameters();
  const std::vector<std::pair<std::string, RosValue>> attempts = {
      {"safety.max_speed.translation", number(0.0)},
      {"safety.max_force.force", number(0.0)},
      {"safety.workspace.stiffness", number(0.0)},
      {"safety.energy_tank.enabled", flag(false)},
      {"limits.joint_torque_rate", number(1e6)},
      {"limits.stiffness.translation.max", number(1e5)},
      {"plausibility.dt.max", number(0.5)},
      {"payload.mass", number(2.0)},
  };
  for (const auto& [name, value] : attempts) {
    const auto result =
        parameters_->set({{"filter.pose.time", number(0.4)}, {name, value}}, nullptr);
    EXPECT_FALSE(result.successful) << name;
    EXPECT_NE(result.reason.find("'" + name + "' of /arm is read-only"), std::string::npos)
        << result.reason;
    EXPECT_NE(result.reason.find("safety settings are locked while the controller runs"),
              std::string::npos)
        << result.reason;
    EXPECT_NE(result.reason.find(name + " = "), std::string::npos) << result.reason;
    EXPECT_NE(result.reason.find("allow_runtime_safety_changes: true"), std::string::npos)
        << result.reason;
  }
  const auto one = parameters_->set({{"safety.max_speed.translation", number(0.0)}}, nullptr);
  EXPECT_NE(one.reason.find("safety.max_speed.translation = 0 m/s (in force: 1 m/s)"),
            std::string::npos)
      << one.reason;
  // The value in force is refused too, as rclcpp refuses any set of a read-only parameter.
  EXPECT_FALSE(
      parameters_->set({{"safety.max_speed.translation", number(1.0)}}, nullptr).successful);
  settle();
  EXPECT_EQ(ci::encode_parameters(loop_->latest_parameters()), ci::encode_parameters(before));
  EXPECT_EQ(loop_->latest_state().safety_changes, 0u);
  // What is not a safety setting still changes.
  EXPECT_TRUE(parameters_->set({{"filter.pose.time", number(0.4)}}, nullptr).successful);
  settle();
  EXPECT_EQ(loop_->latest_parameters().filter.pose.time, 0.4);
}

// Issue 41, item 1: a stiffness commanded on a topic was reverted by a parameter set of
// something else (the set sent every parameter as read before the topic's command was applied).
// A set is now a partial update: the full 6x6 stiffness commanded just before it is kept.
TEST_F(RunningNodeParameters, ASetChangesOnlyWhatItNames) {
  run(false);
  int lost = 0;
  for (int i = 0; i < 30; ++i) {
    ci::Matrix6d full = ci::Vector6d::Constant(300.0 + i).asDiagonal();
    full(0, 2) = full(2, 0) = 20.0;
    loop_->set_stiffness_matrix(full);  // as the command thread sends a topic's stiffness
    const auto result =
        parameters_->set({{"filter.pose.time", number(i % 2 == 0 ? 0.3 : 0.4)}}, nullptr);
    ASSERT_TRUE(result.successful) << result.reason;
    settle();
    if (loop_->latest_state().controller.commanded.stiffness != full) ++lost;
  }
  EXPECT_EQ(lost, 0) << "of 30 topic stiffnesses, lost to a set of filter.pose.time";
}

// Unlocked by the node's configuration: the descriptors are writable, a safety setting changes,
// is counted by the loop and logged as a warning with both values; plausibility.dt must still
// fit the control period (1 kHz: plausibility.dt.max at least 1.5 ms), as at start.
TEST_F(RunningNodeParameters, UnlockedSafetyChangesAreLoggedAndThePeriodStillFits) {
  run(true);
  const auto d = parameters_->describe({"safety.max_speed.translation"});
  ASSERT_TRUE(d && d->size() == 1u);
  EXPECT_FALSE((*d)[0].read_only);
  EXPECT_NE((*d)[0].description.find("logged as a warning"), std::string::npos);

  ::testing::internal::CaptureStderr();
  const auto result = parameters_->set({{"safety.max_speed.translation", number(0.25)}}, nullptr);
  const std::string log = ::testing::internal::GetCapturedStderr();
  ASSERT_TRUE(result.successful) << result.reason;
  EXPECT_NE(log.find("[WARN]"), std::string::npos) << log;
  EXPECT_NE(log.find("safety setting safety.max_speed.translation changed while the controller "
                     "runs: 1 m/s -> 0.25 m/s"),
            std::string::npos)
      << log;
  settle();
  EXPECT_EQ(loop_->latest_parameters().safety.max_speed.translation, 0.25);
  EXPECT_EQ(loop_->latest_state().safety_changes, 1u);

  ::testing::internal::CaptureStderr();
  const auto fast = parameters_->set({{"plausibility.dt.max", number(0.001)}}, nullptr);
  EXPECT_TRUE(::testing::internal::GetCapturedStderr().empty());
  EXPECT_FALSE(fast.successful);
  EXPECT_NE(fast.reason.find("control_rate = 1000 Hz does not fit plausibility.dt = [1e-05, "
                             "0.001] s"),
            std::string::npos)
      << fast.reason;
  EXPECT_NE(fast.reason.find("plausibility.dt.max to at least 0.0015 s"), std::string::npos)
      << fast.reason;
  EXPECT_NE(fast.reason.find("control_rate is fixed while the node runs"), std::string::npos)
      << fast.reason;
  settle();
  EXPECT_EQ(loop_->latest_parameters().plausibility.dt.max, 0.02);
  EXPECT_TRUE(parameters_->set({{"plausibility.dt.max", number(0.002)}}, nullptr).successful);
  settle();
  EXPECT_EQ(loop_->latest_parameters().plausibility.dt.max, 0.002);
  EXPECT_EQ(loop_->latest_state().safety_changes, 2u);
}

// Issue 41, what was left: a change that did not come through a set (the command thread's topics)
// reaches /parameter_events. changes() names the rows whose values in force differ from what the
// events showed, with the value get() shows (a full matrix: its diagonal), once; a set's own rows
// are not reported again.
TEST_F(RunningNodeParameters, ChangesShowWhatTopicsCommandedOnce) {
  run(false);
  const auto named = [](const std::vector<NamedValue>& values, const std::string& name) {
    const auto found = std::find_if(values.begin(), values.end(),
                                    [&](const NamedValue& v) { return v.first == name; });
    return found == values.end() ? std::optional<RosValue>() : found->second;
  };
  parameters_->all();  // the first event: what changes() compares with
  EXPECT_TRUE(parameters_->changes().empty());

  ci::Matrix6d full = ci::Vector6d(350, 360, 370, 30, 31, 32).asDiagonal();
  full(0, 2) = full(2, 0) = 20.0;
  loop_->set_stiffness_matrix(full);
  loop_->set_damping_ratio(ci::Vector6d::Constant(0.8));
  loop_->set_wrench((ci::Vector6d() << 1, 2, 3, 0, 0, 0).finished());
  loop_->set_nullspace_stiffness(ci::JointVector::Constant(1, 12.0));
  settle();
  const std::vector<NamedValue> changes = parameters_->changes();
  std::vector<std::string> names;
  for (const auto& [name, value] : changes) names.push_back(name);
  EXPECT_EQ(names,
            (Names{"stiffness.translation", "stiffness.rotation", "damping_ratio.translation",
                   "damping_ratio.rotation", "nullspace.stiffness", "wrench.force"}));
  EXPECT_EQ(named(changes, "stiffness.translation")->numbers, (std::vector<double>{350, 360, 370}));
  EXPECT_EQ(named(changes, "wrench.force")->numbers, (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(named(changes, "nullspace.stiffness")->numbers, (std::vector<double>{12}));
  // get() shows the same values in force.
  const auto got = parameters_->get({"stiffness.translation"});
  ASSERT_TRUE(got && got->size() == 1u);
  EXPECT_EQ((*got)[0].numbers, (std::vector<double>{350, 360, 370}));
  EXPECT_TRUE(parameters_->changes().empty()) << "reported twice";

  // A set is reported by its own event only; a topic's change after it is reported.
  std::vector<NamedValue> set_event;
  ASSERT_TRUE(parameters_->set({{"filter.pose.time", number(0.3)}}, &set_event).successful);
  ASSERT_EQ(set_event.size(), 1u);
  settle();
  EXPECT_TRUE(parameters_->changes().empty());
  loop_->set_stiffness(ci::Vector6d::Constant(400.0));
  settle();
  const std::vector<NamedValue> after = parameters_->changes();
  ASSERT_TRUE(named(after, "stiffness.translation"));
  EXPECT_FALSE(named(after, "filter.pose.time"));
}

// Issue 11: a value set at run time meets the rules it meets at start, by the same checks. At
// start the loop refuses a per-joint field whose length is neither 1 nor the chain's joint count,
// and the decoder a value out of range; a set at run time is refused with the same messages, and
// the values in force stay.
TEST_F(RunningNodeParameters, RunTimeSetsMeetTheStartTimeRules) {
  run(false);
  const auto numbers = [](std::vector<double> v) {
    RosValue value;
    value.type = cartesian_impedance_ros2::ros_type::kDoubleArray;
    value.numbers = std::move(v);
    return value;
  };
  const ci::Parameters before = loop_->latest_parameters();
  ci::Parameters at_start;
  at_start.nullspace.stiffness = ci::JointVector::Constant(3, 10.0);
  std::string start_message;
  try {
    ci::ControlLoop refused(*model_, at_start);
  } catch (const ci::Error& error) {
    start_message = error.what();
  }
  ASSERT_FALSE(start_message.empty()) << "three nullspace stiffnesses accepted at start";
  const auto result = parameters_->set({{"nullspace.stiffness", numbers({10, 10, 10})}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("nullspace.stiffness"), std::string::npos) << result.reason;
  EXPECT_NE(result.reason.find("3"), std::string::npos) << result.reason;
  const auto negative = parameters_->set({{"damping_ratio.translation", number(-1.0)}}, nullptr);
  EXPECT_FALSE(negative.successful);
  EXPECT_NE(negative.reason.find("damping_ratio.translation"), std::string::npos)
      << negative.reason;
  settle();
  EXPECT_TRUE(ci::changed_parameters(before, loop_->latest_parameters()).none());
}

// Issue 11: the torque-rate check the node makes at start (startup_report(): the stiffest spring
// the limits allow against the torque-rate limit) is made again, by the same function, when an
// unlocked set changes the limits at run time. Before, a set of limits.stiffness.translation.max
// to 30,000 N/m on the Panda was logged only as the change itself.
TEST_F(RunningNodeParameters, ARunTimeLimitChangeGetsTheStartsRateCheck) {
  run(true);
  settle();
  ci::Parameters raised = loop_->latest_parameters();
  raised.limits.stiffness.translation.max = 30000.0;
  const std::vector<ci::node::ReportLine> expected = ci::node::rate_check_report(
      raised, *model_, loop_->latest_state().q, "the current configuration");
  ASSERT_FALSE(expected.empty()) << "30,000 N/m passes the rate check: no case";
  ::testing::internal::CaptureStderr();
  const auto result =
      parameters_->set({{"limits.stiffness.translation.max", number(30000.0)}}, nullptr);
  const std::string log = ::testing::internal::GetCapturedStderr();
  ASSERT_TRUE(result.successful) << result.reason;
  for (const ci::node::ReportLine& line : expected) {
    EXPECT_NE(log.find(line.text), std::string::npos) << line.text << "\nnot in\n" << log;
  }
  // At start the same check says the same about the same configuration.
  const ci::JointVector q = loop_->latest_state().q;
  const auto start = ci::node::startup_report(raised, *model_, &q);
  EXPECT_EQ(start.size(), expected.size() + 1);  // the limits line, then the check's
}

}  // namespace
}  // namespace parameter_services_test
