// The parameter decoder on its own (parameter_tree.hpp): every shape each kind of field accepts,
// every wrong one rejected with its message, unknown and repeated keys, locations in messages, the
// encode -> decode round trip, and the YAML adapter giving the decoder's messages.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <ostream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameter_tree.hpp"
#include "cartesian_impedance/core/parameters.hpp"

namespace ci = cartesian_impedance;

namespace cartesian_impedance {
// How gtest shows a value in a failed expectation.
void PrintTo(const ParameterValue& value, std::ostream* out) {
  *out << value.describe();
}
}  // namespace cartesian_impedance

using Value = ci::ParameterValue;
using Reason = ci::ParameterError::Reason;

namespace {

Value number(double x, std::string location = {}) {
  return Value::number(x, std::move(location));
}

Value numbers(std::vector<double> xs, std::string location = {}) {
  ci::ParameterList items;
  for (double x : xs) items.push_back(Value::number(x, location));
  return Value::list(std::move(items), location);
}

/// {key: value, ...} without locations.
Value map(std::vector<std::pair<std::string, Value>> entries) {
  ci::ParameterMap members;
  for (auto& [key, value] : entries) members.push_back({key, std::move(value), {}});
  return Value::map(std::move(members));
}

/// The message and reason of the ParameterError `call` throws ("" if it throws none).
std::pair<std::string, Reason> error_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const ci::ParameterError& error) {
    return {error.what(), error.reason()};
  }
  return {"", Reason::invalid};
}

std::pair<std::string, Reason> assign_error(std::string_view name, const Value& value) {
  ci::Parameters p;
  return error_of([&] { ci::assign_parameter(p, name, value); });
}

std::string decode_error(const Value& tree) {
  return error_of([&] { ci::decode_parameters(tree); }).first;
}

/// A valid set in which every parameter differs from its default: numbers at a quarter (a
/// limit's min) or three quarters of their row's range, vectors and lists spread over it.
ci::Parameters every_field_changed() {
  ci::Parameters p;
  for (const ci::ParameterInfo& row : ci::parameter_table()) {
    const auto at = [&row](double fraction) { return row.min + (row.max - row.min) * fraction; };
    const bool is_min = row.name.substr(row.name.size() - 4) == ".min";
    const ci::ParameterField field = row.in(p);
    if (auto* value = std::get_if<double*>(&field)) {
      **value = at(is_min ? 0.25 : 0.75);
    } else if (auto* axes = std::get_if<Eigen::Vector3d*>(&field)) {
      **axes = Eigen::Vector3d(at(0.75), at(0.5), at(0.25));
    } else if (auto* joints = std::get_if<ci::JointVector*>(&field)) {
      **joints = ci::JointVector::LinSpaced(7, at(0.25), at(0.75));
    } else if (auto* frame = std::get_if<ci::Frame*>(&field)) {
      **frame = ci::Frame::end_effector;
    } else if (auto* reaction = std::get_if<ci::CollisionReaction*>(&field)) {
      **reaction = ci::CollisionReaction::retract;
    } else if (auto* region = std::get_if<ci::BodyRegion*>(&field)) {
      **region = ci::BodyRegion::hand;
    } else if (auto* flag = std::get_if<bool*>(&field)) {
      **flag = !**flag;
    }
  }
  // The payload's moment must fit under the torque cap (consistency_fault()).
  p.payload.center_of_mass = Eigen::Vector3d(0.075, 0.05, 0.025);
  return p;
}

}  // namespace

TEST(ParameterTree, EveryKindOfFieldAcceptsItsShapes) {
  ci::Parameters p;
  ci::assign_parameter(p, "nullspace.damping_ratio", number(2));  // an integer is a number
  EXPECT_EQ(p.nullspace.damping_ratio, 2.0);
  ci::assign_parameter(p, "stiffness.translation", number(300));
  EXPECT_EQ(p.stiffness.translation, Eigen::Vector3d::Constant(300));
  ci::assign_parameter(p, "stiffness.translation", numbers({1, 2, 3}));
  EXPECT_EQ(p.stiffness.translation, Eigen::Vector3d(1, 2, 3));
  ci::assign_parameter(p, "limits.joint_torque", number(40));
  EXPECT_EQ(p.limits.joint_torque, ci::JointVector::Constant(1, 40));
  ci::assign_parameter(p, "limits.joint_torque", numbers({1, 2}));
  EXPECT_EQ(p.limits.joint_torque, (ci::JointVector(2) << 1, 2).finished());
  ci::assign_parameter(p, "limits.joint_torque", numbers(std::vector<double>(ci::kMaxJoints, 5)));
  EXPECT_EQ(p.limits.joint_torque.size(), ci::kMaxJoints);
  ci::assign_parameter(p, "wrench.frame", Value::string("end_effector"));
  EXPECT_EQ(p.wrench.frame, ci::Frame::end_effector);
  ci::assign_parameter(p, "wrench.frame", Value::string("base"));
  EXPECT_EQ(p.wrench.frame, ci::Frame::base);
  ci::assign_parameter(p, "dynamics.gravity_compensation", Value::boolean(true));
  EXPECT_TRUE(p.dynamics.gravity_compensation);
}

TEST(ParameterTree, EveryWrongShapeIsRejectedWithItsMessage) {
  const std::string joints = std::to_string(ci::kMaxJoints);
  const std::vector<std::tuple<std::string, Value, std::string, Reason>> cases{
      {"filter.pose.time", Value::string("fast"), "filter.pose.time = 'fast' is not a number [s]",
       Reason::wrong_type},
      {"filter.pose.time", Value::boolean(true), "filter.pose.time = true is not a number [s]",
       Reason::wrong_type},
      {"nullspace.damping_ratio", numbers({1, 2}),
       "nullspace.damping_ratio = a list of 2 is not a number", Reason::wrong_type},
      {"nullspace.damping_ratio", map({}), "nullspace.damping_ratio = a map is not a number",
       Reason::wrong_type},
      {"stiffness.translation", numbers({1, 2}),
       "stiffness.translation must be 3 numbers [x, y, z] or one number, got a list of 2",
       Reason::wrong_shape},
      {"stiffness.translation", map({{"x", number(1)}}),
       "stiffness.translation must be 3 numbers [x, y, z] or one number, got a map",
       Reason::wrong_shape},
      {"stiffness.rotation", Value::list({number(1), Value::string("fifty"), number(1)}),
       "stiffness.rotation.y = 'fifty' is not a number [Nm/rad]", Reason::wrong_type},
      {"limits.joint_torque_rate", numbers({}),
       "limits.joint_torque_rate must be one number or a list of 1 to " + joints +
           " numbers (one per joint), got a list of 0",
       Reason::wrong_shape},
      {"limits.joint_torque", numbers(std::vector<double>(ci::kMaxJoints + 1, 1.0)),
       "limits.joint_torque must be one number or a list of 1 to " + joints +
           " numbers (one per joint), got a list of " + std::to_string(ci::kMaxJoints + 1),
       Reason::wrong_shape},
      {"limits.joint_torque", Value::list({number(87), Value::boolean(false)}),
       "limits.joint_torque[1] = false is not a number [Nm]", Reason::wrong_type},
      {"limits.joint_torque", Value::list({number(87), numbers({1})}),
       "limits.joint_torque[1] = a list of 1 is not a number [Nm]", Reason::wrong_type},
      {"wrench.frame", Value::string("tool"),
       "wrench.frame = 'tool' is not a frame (valid: base, end_effector)", Reason::out_of_range},
      {"stiffness.frame", Value::list({Value::string("base")}),
       "stiffness.frame = a list of 1 is not a frame (valid: base, end_effector)",
       Reason::wrong_type},
      {"dynamics.gravity_compensation", number(1),
       "dynamics.gravity_compensation = 1 is not true or false", Reason::wrong_type},
      {"dynamics.gravity_compensation", Value::string("true"),
       "dynamics.gravity_compensation = 'true' is not true or false", Reason::wrong_type},
      {"stiffness.translation", Value(), "stiffness.translation has no value", Reason::no_value},
      {"stiffness.rotation", Value::list({number(1), Value(), number(1)}),
       "stiffness.rotation.y has no value", Reason::no_value},
      {"stiffness.frame", Value(), "stiffness.frame has no value", Reason::no_value},
      {"stiffness.translation", numbers({500, -5, 500}),
       "stiffness.translation.y = -5 N/m is outside [0, 100000]", Reason::out_of_range},
      {"nullspace.stiffness", number(std::numeric_limits<double>::quiet_NaN()),
       "nullspace.stiffness = nan Nm/rad is not finite (valid: [0, 10000])", Reason::out_of_range},
      {"nullspace.damping_ratio", Value::too_large("1e400"),
       "nullspace.damping_ratio = 1e400 overflows a double (valid: [0, 10])", Reason::out_of_range},
      {"stiffness.tranlation", number(1),
       "unknown parameter 'stiffness.tranlation' (did you mean 'stiffness.translation'? valid "
       "in 'stiffness': translation, rotation, frame)",
       Reason::unknown_name},
      {"stiffness", number(1),
       "unknown parameter 'stiffness' (it is a group; give its members: translation, rotation, "
       "frame)",
       Reason::unknown_name},
  };
  for (const auto& [name, value, message, reason] : cases) {
    SCOPED_TRACE(name + " = " + value.describe());
    const auto [what, why] = assign_error(name, value);
    EXPECT_EQ(what, message);
    EXPECT_EQ(static_cast<int>(why), static_cast<int>(reason));
  }
}

TEST(ParameterTree, ARejectedValueChangesNothing) {
  ci::Parameters p;
  EXPECT_THROW(ci::assign_parameter(p, "stiffness.translation", numbers({1, -1, 1})),
               ci::ParameterError);
  EXPECT_THROW(ci::assign_parameter(p, "limits.joint_torque", numbers({50, 0})), ci::Error);
  EXPECT_EQ(ci::encode_parameters(p), ci::encode_parameters(ci::Parameters{}));
  // A whole tree is all or nothing too: decode_parameters() returns a new set or throws.
  const ci::Parameters base = every_field_changed();
  const Value bad =
      map({{"stiffness", map({{"translation", number(1)}, {"rotation", number(-1)}})}});
  EXPECT_THROW(ci::decode_parameters(bad, base), ci::ParameterError);
}

TEST(ParameterTree, SourcesHintAndLocationAreInTheMessage) {
  Value quoted = Value::string("5", "test.yaml:2");
  quoted.hint = "it is quoted";
  EXPECT_EQ(assign_error("nullspace.damping_ratio", quoted).first,
            "test.yaml:2: nullspace.damping_ratio = '5' is not a number (it is quoted)");
  EXPECT_EQ(assign_error("stiffness.rotation", numbers({1, -1, 1}, "p.yaml:7")).first,
            "p.yaml:7: stiffness.rotation.y = -1 Nm/rad is outside [0, 10000]");
  // Key problems are placed at the key, value problems at the value.
  ci::ParameterMap stiffness;
  stiffness.push_back({"rotation", number(-1, "at value"), "at key"});
  stiffness.push_back({"tranlation", number(1, "at value"), "at key"});
  EXPECT_EQ(decode_error(Value::map({{"stiffness", Value::map(stiffness), "g"}})),
            "at value: stiffness.rotation = -1 Nm/rad is outside [0, 10000]");
  stiffness.erase(stiffness.begin());
  EXPECT_EQ(decode_error(Value::map({{"stiffness", Value::map(stiffness), "g"}})),
            "at key: unknown parameter 'stiffness.tranlation' (did you mean "
            "'stiffness.translation'? valid in 'stiffness': translation, rotation, frame)");
  EXPECT_EQ(decode_error(Value::map({{"stiffness.translation", Value(), "line 4"}})),
            "line 4: stiffness.translation has no value");
  // Rules across parameters are the whole source's.
  const Value crossed =
      map({{"limits.damping_ratio.min", number(3)}, {"limits.damping_ratio.max", number(2)}});
  EXPECT_EQ(error_of([&] { ci::decode_parameters(crossed, {}, "arm.yaml"); }).first,
            "arm.yaml: limits.damping_ratio.min = 3 is greater than limits.damping_ratio.max = 2");
  EXPECT_EQ(static_cast<int>(error_of([&] { ci::decode_parameters(crossed); }).second),
            static_cast<int>(Reason::invalid));
}

TEST(ParameterTree, TreesAreNestedDottedOrBoth) {
  const ci::Parameters nested = ci::decode_parameters(
      map({{"stiffness", map({{"translation", number(700)}})},
           {"limits", map({{"stiffness", map({{"rotation", map({{"max", number(400)}})}})}})}}));
  const ci::Parameters dotted = ci::decode_parameters(map(
      {{"stiffness.translation", number(700)}, {"limits.stiffness.rotation.max", number(400)}}));
  const ci::Parameters mixed =
      ci::decode_parameters(map({{"stiffness", map({{"translation", number(700)}})},
                                 {"limits.stiffness", map({{"rotation.max", number(400)}})}}));
  EXPECT_EQ(nested.stiffness.translation, Eigen::Vector3d::Constant(700));
  EXPECT_EQ(nested.limits.stiffness.rotation.max, 400);
  EXPECT_EQ(ci::encode_parameters(dotted), ci::encode_parameters(nested));
  EXPECT_EQ(ci::encode_parameters(mixed), ci::encode_parameters(nested));
  // A group with every member left out, and an empty tree, change nothing.
  EXPECT_EQ(ci::encode_parameters(ci::decode_parameters(map({{"filter", Value()}}))),
            ci::encode_parameters(ci::Parameters{}));
  EXPECT_EQ(ci::encode_parameters(ci::decode_parameters(Value(), dotted)),
            ci::encode_parameters(dotted));
}

TEST(ParameterTree, UnknownRepeatedAndMisplacedKeysAreNamed) {
  EXPECT_EQ(decode_error(map({{"stifness", map({{"translation", number(1)}})}})),
            "unknown parameter 'stifness' (did you mean 'stiffness'? valid top-level names: "
            "stiffness, damping_ratio, minimum_damping, nullspace, wrench, filter, limits, "
            "dynamics, joint_limit_avoidance, trajectory, plausibility, safety, payload, "
            "collision)");
  EXPECT_EQ(decode_error(map({{"limits", map({{"stiffness", map({{"mxa", number(1)}})}})}})),
            "unknown parameter 'limits.stiffness.mxa' (valid in 'limits.stiffness': "
            "translation, rotation)");
  EXPECT_EQ(decode_error(map({{"filter", number(0.5)}})),
            "unknown parameter 'filter' (it is a group; give its members: pose, stiffness, "
            "nullspace, wrench)");
  EXPECT_EQ(decode_error(map({{"limits.stiffness", numbers({1, 2})}})),
            "unknown parameter 'limits.stiffness' (it is a group; give its members: translation, "
            "rotation)");
  EXPECT_EQ(decode_error(map({{"filter.pose.time", number(0.1)},
                              {"filter", map({{"pose", map({{"time", number(0.2)}})}})}})),
            "'filter.pose.time' is given twice; expected each key once");
  ci::ParameterMap twice;
  twice.push_back({"stiffness.translation", number(1), "a.yaml:1"});
  twice.push_back({"stiffness", Value::map({{"translation", number(2), "a.yaml:3"}}), "a.yaml:2"});
  EXPECT_EQ(decode_error(Value::map(twice)),
            "a.yaml:3: 'stiffness.translation' is given twice (first at a.yaml:1); expected each "
            "key once");
  EXPECT_EQ(decode_error(numbers({1, 2}, "a.yaml:1")),
            "a.yaml:1: the top level must be a map of parameters, got a list of 2");
}

TEST(ParameterTree, EncodeThenDecodeGivesTheSameParameters) {
  for (const ci::Parameters& p : {ci::Parameters{}, every_field_changed()}) {
    for (ci::KeyLayout layout : {ci::KeyLayout::nested, ci::KeyLayout::dotted}) {
      const Value tree = ci::encode_parameters(p, layout);
      const ci::Parameters back = ci::decode_parameters(tree);
      EXPECT_EQ(ci::encode_parameters(back, layout), tree);
      for (const ci::ParameterInfo& row : ci::parameter_table()) {
        EXPECT_EQ(ci::value_text(back, row), ci::value_text(p, row)) << row.name;
      }
    }
  }
  // Every field of the changed set differs from its default, so a lost field would show.
  const ci::Parameters changed = every_field_changed();
  for (const ci::ParameterInfo& row : ci::parameter_table()) {
    EXPECT_NE(ci::value_text(changed, row), ci::value_text(ci::Parameters{}, row)) << row.name;
  }
  // The nested tree has the table's groups, in table order.
  const Value tree = ci::encode_parameters(ci::Parameters{});
  ASSERT_TRUE(tree.is(Value::Kind::map));
  EXPECT_EQ(tree.as_map().front().key, "stiffness");
  EXPECT_EQ(*tree.member("limits")->member("stiffness")->member("translation")->member("max"),
            number(5000));
  EXPECT_EQ(*tree.member("limits")->member("joint_torque"), numbers({}));  // the URDF's
  EXPECT_EQ(*tree.member("wrench")->member("frame"), Value::string("base"));
  EXPECT_EQ(ci::encode_parameters(ci::Parameters{}, ci::KeyLayout::dotted).as_map().size(),
            ci::parameter_table().size());
}

TEST(ParameterTree, SettingsOfASourceAreDecodedLikeParameters) {
  const ci::ParameterInfo rate{"control_rate", "Hz", 0, 10000, true, "", nullptr};
  EXPECT_EQ(ci::decode_number(number(500), rate, "control_rate"), 500);
  EXPECT_EQ(error_of([&] {
              ci::decode_number(number(0, "ns/control_rate"), rate, "control_rate");
            }).first,
            "ns/control_rate: control_rate = 0 Hz is outside (0, 10000]");
  const ci::ParameterInfo priority{"realtime_priority", "", 0, 99, false, "", nullptr};
  EXPECT_EQ(ci::decode_integer(number(80), priority, "realtime_priority"), 80);
  EXPECT_EQ(error_of([&] { ci::decode_integer(number(8.5), priority, "realtime_priority"); }).first,
            "realtime_priority = 8.5 is not a whole number");
  EXPECT_EQ(ci::decode_name(Value::string("sim"), "mode", "a mode", {"sim", "topics"}), "sim");
  EXPECT_EQ(error_of([&] {
              ci::decode_name(Value::string("hardware"), "mode", "a mode", {"sim", "topics"});
            }).first,
            "mode = 'hardware' is not a mode (valid: sim, topics)");
  EXPECT_EQ(error_of([&] { ci::decode_name(number(5), "base_link", "a link name"); }).first,
            "base_link = 5 is not a link name");
  // frame_from_name() gives the decoder's message.
  EXPECT_EQ(error_of([] { ci::frame_from_name("frame", "world"); }).first,
            "frame = 'world' is not a frame (valid: base, end_effector)");
  EXPECT_EQ(error_of([] { ci::parameter_info("limits"); }).first,
            "unknown parameter 'limits' (it is a group; give its members: stiffness, "
            "damping_ratio, nullspace_stiffness, wrench, pose_error, joint_torque, "
            "joint_torque_rate)");
}

TEST(ParameterTree, ValuesDescribeThemselvesAndCompareByContent) {
  EXPECT_EQ(Value().describe(), "nothing");
  EXPECT_EQ(number(0.5).describe(), "0.5");
  EXPECT_EQ(Value::too_large("-1e999", true).describe(), "-1e999");
  EXPECT_EQ(Value::boolean(false).describe(), "false");
  EXPECT_EQ(Value::string("x").describe(), "'x'");
  EXPECT_EQ(numbers({1, 2, 3}).describe(), "a list of 3");
  EXPECT_EQ(map({}).describe(), "a map");
  EXPECT_EQ(number(1, "here"), number(1, "there"));
  EXPECT_NE(number(1), Value::boolean(true));
  EXPECT_NE(map({{"a", number(1)}}), map({{"b", number(1)}}));
  EXPECT_NE(Value::too_large("1e400"), number(std::numeric_limits<double>::infinity()));
  EXPECT_EQ(map({{"a", number(1)}}).member("b"), nullptr);
}

// ---- the YAML adapter -----------------------------------------------------------------------

namespace {

std::string yaml_error(const std::string& yaml) {
  try {
    ci::parameters_from_yaml(yaml, "test.yaml");
  } catch (const ci::Error& error) {
    return error.what();
  }
  return "";
}

}  // namespace

TEST(ParameterTreeYaml, GivesTheDecodersMessageAfterFileAndLine) {
  // The same mistake as a tree without locations (how a Python dict arrives) and as YAML.
  const std::vector<std::tuple<std::string, Value, std::string>> mistakes{
      {"filter.pose.time", Value::string("fast"), "filter:\n  pose:\n    time: fast\n"},
      {"filter.pose.time", Value::boolean(true), "filter:\n  pose:\n    time: true\n"},
      {"stiffness.translation", numbers({1, 2}), "stiffness:\n  translation: [1, 2]\n"},
      {"stiffness.rotation", numbers({1, -1, 1}), "stiffness:\n  rotation: [1, -1, 1]\n"},
      {"limits.joint_torque_rate", numbers({}), "limits:\n  joint_torque_rate: []\n"},
      {"wrench.frame", Value::string("tool"), "wrench:\n  frame: tool\n"},
      {"dynamics.gravity_compensation", number(1), "dynamics:\n  gravity_compensation: 1\n"},
      {"stiffness.tranlation", number(1), "stiffness:\n  tranlation: 1\n"},
  };
  for (const auto& [name, value, yaml] : mistakes) {
    SCOPED_TRACE(yaml);
    const std::string message = assign_error(name, value).first;
    ASSERT_FALSE(message.empty());
    const std::string line = name.find("filter") == 0 ? "3" : "2";
    EXPECT_EQ(yaml_error(yaml), "test.yaml:" + line + ": " + message);
  }
}

TEST(ParameterTreeYaml, StringsThatLookLikeNumbersSayWhy) {
  EXPECT_EQ(yaml_error("nullspace:\n  damping_ratio: '5'\n"),
            "test.yaml:2: nullspace.damping_ratio = '5' is not a number (it is quoted or a block "
            "scalar, which makes it a string in YAML: write it without quotes)");
  EXPECT_EQ(yaml_error("nullspace:\n  damping_ratio: !!float 5\n"),
            "test.yaml:2: nullspace.damping_ratio = '5' is not a number (it has the tag !!float: "
            "write it without a tag)");
  EXPECT_EQ(yaml_error("stiffness:\n  translation:\n"),
            "test.yaml:2: stiffness.translation has no value");
  EXPECT_EQ(yaml_error("stiffness.translation: 1\nstiffness:\n  translation: 2\n"),
            "test.yaml:3: 'stiffness.translation' is given twice (first at test.yaml:1); expected "
            "each key once");
}

TEST(ParameterTreeYaml, AliasesCannotMultiplyTheInput) {
  // "Billion laughs": each line names the previous list ten times.
  std::string yaml = "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n";
  for (char name = 'b'; name <= 'i'; ++name) {
    const std::string previous(1, static_cast<char>(name - 1));
    yaml += std::string(1, name) + ": &" + name + " [";
    for (int i = 0; i < 10; ++i) yaml += (i ? ", *" : "*") + previous;
    yaml += "]\n";
  }
  const std::string message = yaml_error(yaml);
  EXPECT_EQ(message.find("test.yaml:"), 0u) << message;
  EXPECT_NE(message.find("more than 100000 values"), std::string::npos) << message;
  // A list holding itself is refused where the converter finds it again (ParameterTreeGuard).
  EXPECT_EQ(yaml_error("limits:\n  joint_torque: &l [1, *l]\n"),
            "test.yaml:2: 'limits.joint_torque[1]' is 'limits.joint_torque' again: a list or map "
            "that contains itself has no end; a parameter value is a tree");
}
