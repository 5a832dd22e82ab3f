// The YAML loader: unknown keys, wrong shapes, non-numbers, non-finite and out-of-range values,
// malformed and unusual YAML are rejected naming the file, the line and the parameter; one number
// is broadcast; the round trip keeps every value exactly.

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "support/validation_harness.hpp"

namespace ci = cartesian_impedance;
using namespace validation_harness;

namespace {

// ---------------------------------------------------------------------------------------------
// YAML loader

/// parameters_from_yaml(yaml, "test.yaml") throws ci::Error whose message contains every part.
::testing::AssertionResult yaml_rejected_with(const std::string& yaml,
                                              const std::vector<std::string>& parts) {
  ::testing::AssertionResult result =
      rejected_with([&] { ci::parameters_from_yaml(yaml, "test.yaml"); }, parts);
  if (!result) result << "\nfor YAML:\n" << yaml;
  return result;
}

/// A file in a fresh scratch directory, removed with the object.
class TemporaryFile {
 public:
  TemporaryFile(const std::string& name, const std::string& text) {
    const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = ::testing::TempDir() + "validation_test_" + std::to_string(::getpid()) + "_" +
            test->name() + "_" + name;
    std::ofstream(path_) << text;
  }
  ~TemporaryFile() { std::remove(path_.c_str()); }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// Nested block YAML setting the dotted `name` to `value`; `line` receives the value's line.
std::string nested_yaml(std::string_view name, const std::string& value, int& line) {
  std::string yaml;
  std::string indent;
  line = 1;
  for (std::size_t dot; (dot = name.find('.')) != std::string_view::npos; ++line) {
    yaml += indent + std::string(name.substr(0, dot)) + ":\n";
    name.remove_prefix(dot + 1);
    indent += "  ";
  }
  return yaml + indent + std::string(name) + ": " + value + "\n";
}

TEST(YamlConfig, UnknownTopLevelKeyIsNamedWithItsLine) {
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  translation: 500\nstifness:\n  rotation: 5\n",
                                 {"test.yaml:3:", "unknown parameter", "'stifness'"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: 1\ngain: 5\n",
                                 {"test.yaml:3:", "unknown parameter", "'gain'"}));
}

TEST(YamlConfig, UnknownNestedKeyIsNamedByItsDottedPathAndLine) {
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  rotation: 5\n  tranlation: [1, 2, 3]\n",
                                 {"test.yaml:3:", "unknown parameter", "'stiffness.tranlation'"}));
  EXPECT_TRUE(
      yaml_rejected_with("limits:\n  stiffness:\n    translation:\n      min: 1\n      mxa: 5\n",
                         {"test.yaml:5:", "'limits.stiffness.translation.mxa'"}));
  EXPECT_TRUE(
      yaml_rejected_with("filter:\n  poses:\n    time: 0.1\n", {"test.yaml:2:", "'filter.poses'"}));
}

TEST(YamlConfig, GroupGivenAsScalarOrListIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("filter: 0.5\n", {"test.yaml:1:", "'filter'", "group"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  stiffness: 100\n",
                                 {"test.yaml:2:", "'limits.stiffness'", "group"}));
  EXPECT_TRUE(
      yaml_rejected_with("stiffness: [500, 500, 500]\n", {"test.yaml:1:", "'stiffness'", "group"}));
}

TEST(YamlConfig, ValueOfTheWrongShapeIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  translation: [500, 500]\n",
                                 {"test.yaml:2:", "stiffness.translation", "3 numbers", "2"}));
  EXPECT_TRUE(yaml_rejected_with("wrench:\n  torque: [1, 2, 3, 4]\n",
                                 {"test.yaml:2:", "wrench.torque", "3 numbers", "4"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  joint_torque_rate: []\n",
                                 {"test.yaml:2:", "limits.joint_torque_rate", "one per joint"}));
  std::string too_many = "limits:\n  joint_torque: [1";
  for (int i = 0; i < ci::kMaxJoints; ++i) too_many += ", 1";  // kMaxJoints + 1 values
  EXPECT_TRUE(yaml_rejected_with(too_many + "]\n",
                                 {"test.yaml:2:", "limits.joint_torque", "one per joint"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: [1, 2]\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "not a number"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  frame: [base]\n",
                                 {"test.yaml:2:", assigned("stiffness.frame", "a list of 1"),
                                  "is not a frame (valid: base, end_effector)"}));
}

TEST(YamlConfig, ParameterGivenAsMapIsAShapeErrorNotAnUnknownKey) {
  // The parameter exists; calling it unknown would send the user looking for a typo.
  const std::vector<std::pair<std::string, std::string>> cases{
      {"stiffness:\n  translation:\n    x: 1\n    y: 2\n    z: 3\n", "stiffness.translation"},
      {"nullspace:\n  damping_ratio:\n    value: 1\n", "nullspace.damping_ratio"},
      {"limits:\n  joint_torque:\n    all: 50\n", "limits.joint_torque"}};
  for (const auto& [yaml, name] : cases) {
    std::string message;
    ASSERT_TRUE(throws_error([&] { ci::parameters_from_yaml(yaml, "test.yaml"); }, message));
    EXPECT_TRUE(contains_all(message, {"test.yaml:", name}));
    EXPECT_EQ(message.find("unknown parameter"), std::string::npos) << message;
  }
}

TEST(YamlConfig, NonNumberIsRejectedNamingTheElement) {
  EXPECT_TRUE(yaml_rejected_with(
      "nullspace:\n  damping_ratio: abc\n",
      {"test.yaml:2:", assigned("nullspace.damping_ratio", "'abc'"), "not a number"}));
  EXPECT_TRUE(yaml_rejected_with(
      "stiffness:\n  rotation: [50, fifty, 50]\n",
      {"test.yaml:2:", assigned("stiffness.rotation.y", "'fifty'"), "not a number"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  joint_torque: [87, 87, 87, 87x, 12, 12, 12]\n",
                                 {"test.yaml:2:", assigned("limits.joint_torque[3]", "'87x'")}));
  EXPECT_TRUE(yaml_rejected_with(
      "filter:\n  pose:\n    time: true\n",
      {"test.yaml:3:", assigned("filter.pose.time", "true"), "is not a number [s]"}));
}

TEST(YamlConfig, EveryTableRowRejectsNanAndInfinityWithItsLine) {
  const std::array<std::pair<const char*, const char*>, 3> kYamlPoisons{
      {{".nan", "nan"}, {".inf", "inf"}, {"-.inf", "-inf"}}};
  int elements_checked = 0;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    ci::Parameters defaults;
    const ci::ParameterField field = info.in(defaults);
    if (!ci::choice_names(field).empty() || std::holds_alternative<bool*>(field)) continue;
    const bool three = std::holds_alternative<Eigen::Vector3d*>(field);
    const bool per_joint = std::holds_alternative<ci::JointVector*>(field);
    const int count = three ? 3 : per_joint ? kJoints : 1;
    for (int i = 0; i < count; ++i) {
      ++elements_checked;
      std::string element(info.name);
      if (three) element += std::string(".") + kAxes[i];
      if (per_joint) element += "[" + std::to_string(i) + "]";
      for (const auto& [yaml_value, text] : kYamlPoisons) {
        std::string value = yaml_value;
        if (count > 1) {
          value = "[";
          for (int j = 0; j < count; ++j)
            value += (j ? ", " : "") + std::string(j == i ? yaml_value : "1");
          value += "]";
        }
        int line = 0;
        const std::string yaml = nested_yaml(info.name, value, line);
        EXPECT_TRUE(yaml_rejected_with(yaml, {"test.yaml:" + std::to_string(line) + ":",
                                              assigned(element, text), info.range_text()}));
      }
    }
  }
  EXPECT_EQ(elements_checked, 9 * 3 + 6 * 7 + 49);
}

TEST(YamlConfig, OutOfRangeValueIsReportedWithFileAndLine) {
  const TemporaryFile file("out_of_range.yaml",
                           "# comment\nstiffness:\n  translation: [500, -5, 500]\n");
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(file.path()); },
                            {file.path() + ":3:", assigned("stiffness.translation.y", "-5 N/m"),
                             "is outside [0, 100000]"}));
  const TemporaryFile fraction("fraction.yaml", "filter:\n  nullspace:\n    fraction: 1.5\n");
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(fraction.path()); },
                            {fraction.path() + ":3:", assigned("filter.nullspace.fraction", "1.5"),
                             "is outside [0.5, 1]"}));
  EXPECT_TRUE(yaml_rejected_with(
      "limits:\n  pose_error:\n    translation: 0\n",
      {"test.yaml:3:", assigned("limits.pose_error.translation", "0 m"), "is outside [0.01, 10]"}));
}

TEST(YamlConfig, MinGreaterThanMaxAcrossFieldsIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("limits:\n  damping_ratio:\n    min: 3\n    max: 2\n",
                                 {"test.yaml", assigned("limits.damping_ratio.min", "3"),
                                  assigned("limits.damping_ratio.max", "2"), "greater than"}));
  // max alone below the default min is just as wrong.
  EXPECT_TRUE(
      yaml_rejected_with("limits:\n  stiffness:\n    rotation:\n      min: 100\n      max: 50\n",
                         {assigned("limits.stiffness.rotation.min", "100 Nm/rad"),
                          assigned("limits.stiffness.rotation.max", "50 Nm/rad")}));
}

TEST(YamlConfig, MissingFileIsNamed) {
  const std::string path = "/nonexistent/cartesian_impedance/params.yaml";
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(path); }, {path}));
}

TEST(YamlConfig, DirectoryIsNotAParameterFile) {
  // Opening a directory succeeds on Linux and reads nothing; it must not pass for an empty file.
  const std::string path = ::testing::TempDir();
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(path); }, {path}));
}

TEST(YamlConfig, MalformedYamlIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("stiffness: [1, 2\n", {"test.yaml", "malformed YAML"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  translation: 1\n rotation: 2\n",
                                 {"test.yaml", "malformed YAML"}));
  EXPECT_TRUE(yaml_rejected_with("- 1\n- 2\n", {"test.yaml", "top level must be a map"}));
  EXPECT_TRUE(yaml_rejected_with("just text\n", {"test.yaml", "top level must be a map"}));
  const TemporaryFile file("malformed.yaml", "filter: {pose: \n");
  EXPECT_TRUE(
      rejected_with([&] { ci::load_parameters(file.path()); }, {file.path(), "malformed YAML"}));
}

TEST(YamlConfig, ComplexKeyIsAnErrorNotAYamlCppException) {
  // A key that is a list or map made yaml-cpp throw its own TypedBadConversion.
  EXPECT_TRUE(yaml_rejected_with("? [a, b]\n: 1\n", {"test.yaml:1:", "key", "a list"}));
  EXPECT_TRUE(yaml_rejected_with("{[1,2]: 3}\n", {"test.yaml:1:", "key", "a list"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  ? {a: 1}\n  : 1\n",
                                 {"test.yaml:2:", "in stiffness", "key", "a map"}));
  EXPECT_TRUE(
      yaml_rejected_with("stiffness:\n  ~: 1\n", {"test.yaml:2:", "in stiffness", "key", "empty"}));
}

TEST(YamlConfig, DuplicateKeyIsRejectedNamingTheKeyAndBothLines) {
  // yaml-cpp keeps both entries and the loader read the last: a silent override.
  EXPECT_TRUE(yaml_rejected_with("stiffness: {translation: 1}\nstiffness: {translation: 2}\n",
                                 {"test.yaml:2:", "'stiffness'", "twice", "lines 1 and 2"}));
  EXPECT_TRUE(
      yaml_rejected_with("stiffness:\n  translation: 1\n  rotation: 2\n  translation: 3\n",
                         {"test.yaml:4:", "'stiffness.translation'", "twice", "lines 2 and 4"}));
  EXPECT_TRUE(yaml_rejected_with("filter: {pose: {time: 0.1, time: 0.2}}\n",
                                 {"test.yaml:1:", "'filter.pose.time'", "twice", "lines 1 and 1"}));
}

TEST(YamlConfig, SecondDocumentIsRejected) {
  // YAML::Load read the first document and ignored the rest.
  EXPECT_TRUE(
      yaml_rejected_with("stiffness:\n  translation: 1\n---\nstiffness:\n  translation: 2\n",
                         {"test.yaml:4:", "a second YAML document", "only one document"}));
  EXPECT_TRUE(yaml_rejected_with("---\nstiffness:\n  translation: 1\n---\n",
                                 {"test.yaml", "second YAML document", "only one document"}));
  // One document between explicit markers is fine.
  EXPECT_EQ(
      ci::parameters_from_yaml("---\nstiffness:\n  translation: 700\n...\n").stiffness.translation,
      Eigen::Vector3d::Constant(700));
}

TEST(YamlConfig, QuotedNumberOrSwitchIsAStringAndRejected) {
  // yaml-cpp converts the text of any scalar; in YAML quotes make a string, whatever it reads.
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: '5'\n",
                                 {"test.yaml:2:", assigned("nullspace.damping_ratio", "'5'"),
                                  "quoted", "string", "without quotes"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  rotation: [50, \"50\", 50]\n",
                                 {"test.yaml:2:", "stiffness.rotation.y", "quoted"}));
  EXPECT_TRUE(yaml_rejected_with("dynamics:\n  gravity_compensation: 'true'\n",
                                 {"test.yaml:2:", "dynamics.gravity_compensation", "quoted"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: ' 5'\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "quoted"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: |\n    5\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "string"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: !!str 5\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "tag", "!!str"}));
  EXPECT_TRUE(yaml_rejected_with("dynamics:\n  gravity_compensation: !!bool true\n",
                                 {"test.yaml:2:", "dynamics.gravity_compensation", "tag"}));
  // A frame is a name, quoted or not.
  EXPECT_EQ(ci::parameters_from_yaml("stiffness:\n  frame: 'end_effector'\n").stiffness.frame,
            ci::Frame::end_effector);
}

TEST(YamlConfig, UnusualNumberSpellingsAreDecidedExplicitly) {
  const std::string range = ci::parameter_info("nullspace.damping_ratio").range_text();
  const auto damping = [](const std::string& value) {
    return "nullspace:\n  damping_ratio: " + value + "\n";
  };
  // Too large for a double: rejected with the range, as .nan and .inf are (see above).
  EXPECT_TRUE(yaml_rejected_with(
      damping("1e400"),
      {"test.yaml:2:", assigned("nullspace.damping_ratio", "1e400"), "overflows", range}));
  EXPECT_TRUE(yaml_rejected_with(damping("-1e400"), {"test.yaml:2:", "-1e400", "overflows"}));
  // Integer forms of YAML 1.1/1.2 that yaml-cpp does not read as numbers, and other words.
  for (const char* spelling : {"0x10", "0o17", "0b101", "1_000", "nan", "inf", "1,5", "5 5"}) {
    EXPECT_TRUE(yaml_rejected_with(
        damping(spelling), {"test.yaml:2:", "'" + std::string(spelling) + "'", "is not a number"}));
  }
  // What is a number is read as one: decimal forms, and values that round to a double (5e-324
  // is the smallest subnormal, 1e-400 rounds to 0 as every decimal parser rounds it).
  const std::vector<std::pair<std::string, double>> numbers{
      {"+0.5", 0.5}, {"0005", 5},        {"1.", 1},      {".5", 0.5},
      {"-0", 0.0},   {"5e-324", 5e-324}, {"1e-400", 0.0}};
  for (const auto& [text, value] : numbers) {
    SCOPED_TRACE(text);
    ci::Parameters p;
    ASSERT_NO_THROW(p = ci::parameters_from_yaml("stiffness:\n  rotation: " + text + "\n"));
    EXPECT_EQ(p.stiffness.rotation, Eigen::Vector3d::Constant(value));
  }
  // An integer beyond 2^53 is a number too, rounded to a double (and then checked against the
  // range, whatever that is).
  try {
    EXPECT_EQ(ci::parameters_from_yaml("stiffness:\n  rotation: 99999999999999999999999\n")
                  .stiffness.rotation,
              Eigen::Vector3d::Constant(1e23));
  } catch (const ci::Error& error) {
    EXPECT_TRUE(contains_all(error.what(), {assigned("stiffness.rotation", "1e+23"), "outside"}));
  }
  // Anchors and aliases are plain YAML; a merge key is a key the loader does not know.
  const ci::Parameters p =
      ci::parameters_from_yaml("stiffness:\n  translation: &k 700\n  rotation: *k\n");
  EXPECT_EQ(p.stiffness.rotation, Eigen::Vector3d::Constant(700));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  <<: {translation: 1}\n",
                                 {"test.yaml:2:", "'stiffness.<<'", "merge keys"}));
  // A list or map holding itself is refused where it is used again, naming both paths.
  EXPECT_TRUE(yaml_rejected_with("stiffness: &s\n  translation: 1\n  again: *s\n",
                                 {"test.yaml:3:", "'stiffness.again' is 'stiffness' again"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness: &s {stiffness: *s}\n",
                                 {"test.yaml:1:", "'stiffness.stiffness'"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  joint_torque: &l [1, *l]\n",
                                 {"test.yaml:2:", "limits.joint_torque[1]", "a list"}));
}

TEST(YamlConfig, DeepNestingIsRejectedWithoutCrashing) {
  // yaml-cpp's parser recurses once per level and stops itself at a depth it bounds; the loader
  // reports that, and never descends further than the parameter groups go.
  for (const char* open : {"[", "{", "{a: ", "[{a: "}) {
    std::string yaml = "stiffness:\n  translation: ";
    for (int i = 0; i < 100000; ++i) yaml += open;
    EXPECT_TRUE(yaml_rejected_with(yaml, {"test.yaml:", "nested too deeply"})) << open;
  }
  std::string block;
  for (int i = 0; i < 2000; ++i) block += std::string(static_cast<std::size_t>(i), ' ') + "a:\n";
  EXPECT_TRUE(yaml_rejected_with(block, {"test.yaml:", "nested too deeply"}));
}

TEST(YamlConfig, EmptyInputGivesDefaults) {
  const ci::Parameters defaults;
  for (const char* yaml : {"", "\n", "# nothing set\n", "---\n"}) {
    ci::Parameters p = other_valid_parameters();
    ASSERT_NO_THROW(p = ci::parameters_from_yaml(yaml)) << yaml;
    EXPECT_EQ(first_difference(p, defaults), "") << yaml;
  }
  const TemporaryFile file("empty.yaml", "");
  ci::Parameters p = other_valid_parameters();
  ASSERT_NO_THROW(p = ci::load_parameters(file.path()));
  EXPECT_EQ(first_difference(p, defaults), "");
}

TEST(YamlConfig, OneNumberIsBroadcastToThreeAxesAndAllJoints) {
  const ci::Parameters p = ci::parameters_from_yaml(
      "stiffness:\n  translation: 300\n  rotation: 30\nnullspace:\n  stiffness: 20\n"
      "limits:\n  joint_torque: 40\n");
  EXPECT_TRUE(same_bits(p.stiffness.translation, Eigen::Vector3d::Constant(300)));
  EXPECT_TRUE(same_bits(p.stiffness.rotation, Eigen::Vector3d::Constant(30)));
  EXPECT_TRUE(same_bits(p.nullspace.stiffness, joints({20})));
  EXPECT_TRUE(same_bits(p.limits.joint_torque, joints({40})));

  ci::CartesianImpedanceController controller(kJoints, p);
  EXPECT_TRUE(same_bits(controller.state().commanded.nullspace_stiffness,
                        ci::JointVector::Constant(kJoints, 20)));
  EXPECT_TRUE(same_bits(ci::per_joint(controller.parameters().limits.joint_torque, kJoints),
                        ci::JointVector::Constant(kJoints, 40)));
  ci::Vector6d diagonal = controller.state().commanded.stiffness.diagonal();
  EXPECT_TRUE(same_bits(diagonal, six(300, 300, 300, 30, 30, 30)));
}

TEST(YamlConfig, PerJointListMustMatchTheControllersJointCount) {
  const ci::Parameters p =
      ci::parameters_from_yaml("limits:\n  joint_torque: [87, 87, 87, 87, 12, 12]\n");
  EXPECT_TRUE(rejected_with([&] { ci::CartesianImpedanceController controller(kJoints, p); },
                            {"limits.joint_torque has 6 values", "7"}));
  EXPECT_NO_THROW(ci::CartesianImpedanceController(6, p));
}

TEST(YamlConfig, FramesAreReadAndAnInvalidFrameIsRejected) {
  ci::Parameters p =
      ci::parameters_from_yaml("stiffness:\n  frame: end_effector\nwrench:\n  frame: base\n");
  EXPECT_EQ(p.stiffness.frame, ci::Frame::end_effector);
  EXPECT_EQ(p.wrench.frame, ci::Frame::base);
  p = ci::parameters_from_yaml("stiffness:\n  frame: base\nwrench:\n  frame: end_effector\n");
  EXPECT_EQ(p.stiffness.frame, ci::Frame::base);
  EXPECT_EQ(p.wrench.frame, ci::Frame::end_effector);
  EXPECT_TRUE(yaml_rejected_with("wrench:\n  frame: tool\n",
                                 {"test.yaml:2:", "wrench.frame", "'tool'", "base, end_effector"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  frame: Base\n",
                                 {"test.yaml:2:", "stiffness.frame", "'Base'"}));
}

TEST(YamlConfig, RoundTripKeepsEveryNonDefaultValueExactly) {
  ci::Parameters p = other_valid_parameters();
  // Values that need all 17 significant digits.
  p.stiffness.translation.x() = 1.0 / 3.0;
  p.filter.pose.fraction = 0.4 + 0.2;
  p.limits.pose_error.rotation = 0.1 / 3.0;
  p.limits.joint_torque[4] = 11.000000000000002;
  // The switches, all away from their defaults.
  p.dynamics.gravity_compensation = true;
  p.dynamics.inertia_shaped_damping = false;
  p.dynamics.dynamically_consistent_nullspace = true;
  {
    // Every row differs from its default, so a loader that ignores a key would show.
    const ci::Parameters defaults;
    for (const ci::ParameterInfo& info : ci::parameter_table()) {
      EXPECT_NE(ci::value_text(p, info), ci::value_text(defaults, info)) << info.name;
    }
  }
  const std::string yaml = ci::parameters_to_yaml(p);
  ci::Parameters back;
  ASSERT_NO_THROW(back = ci::parameters_from_yaml(yaml, "round trip")) << yaml;
  EXPECT_EQ(first_difference(p, back), "") << "emitted YAML:\n" << yaml;
  EXPECT_EQ(ci::parameters_to_yaml(back), yaml);
}

TEST(YamlConfig, RoundTripOfSeededRandomParameters) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(0, 1);
  std::uniform_int_distribution<int> joint_count(1, ci::kMaxJoints);
  for (int iteration = 0; iteration < 50; ++iteration) {
    SCOPED_TRACE(iteration);
    ci::Parameters p;
    for (const ci::ParameterInfo& info : ci::parameter_table()) {
      const ci::ParameterField field = info.in(p);
      if (const std::vector<std::string_view> names = ci::choice_names(field); !names.empty()) {
        const auto pick =
            static_cast<std::size_t>(unit(random) * static_cast<double>(names.size()));
        ci::set_choice(field, info.name, names[std::min(pick, names.size() - 1)]);
        continue;
      }
      if (auto* flag = std::get_if<bool*>(&field)) {
        **flag = unit(random) < 0.5;
        continue;
      }
      if (auto* values = std::get_if<ci::JointVector*>(&field)) {
        **values = ci::JointVector::Zero(joint_count(random));
      }
      for_each_element(info, p, [&](const std::string&, double& value) {
        // Log-uniform over the valid range (down to a millionth of its top), either sign where
        // negative values are valid.
        const double low = std::max(info.min, 1e-6 * info.max);
        value = low * std::pow(info.max / low, unit(random));
        if (info.min < 0 && unit(random) < 0.5) value = -value;
      });
    }
    for (ci::Range* range :
         {&p.limits.stiffness.translation, &p.limits.stiffness.rotation, &p.limits.damping_ratio,
          &p.limits.nullspace_stiffness, &p.plausibility.dt}) {
      if (range->min > range->max) std::swap(range->min, range->max);
    }
    for (int i = 0; i < 3; ++i) {
      double& low = p.safety.workspace.min[i];
      double& high = p.safety.workspace.max[i];
      if (low > high) std::swap(low, high);
    }
    ci::EnergyTankParameters& tank = p.safety.energy_tank;
    if (tank.initial > tank.capacity) std::swap(tank.initial, tank.capacity);
    // A declared payload the force caps can hold (consistency_fault()).
    const double g = ci::CartesianImpedanceController::kGravity;
    ci::PayloadParameters& payload = p.payload;
    const ci::MaxForceParameters& cap = p.safety.max_force;
    if (cap.force > 0.0) payload.mass = std::min(payload.mass, 0.999 * cap.force / g);
    const double moment = payload.mass * g * payload.center_of_mass.norm();
    if (cap.torque > 0.0 && moment > cap.torque) {
      payload.center_of_mass *= 0.999 * cap.torque / moment;
    }
    ASSERT_NO_THROW(ci::validate(p));
    const std::string yaml = ci::parameters_to_yaml(p);
    ci::Parameters back;
    ASSERT_NO_THROW(back = ci::parameters_from_yaml(yaml)) << yaml;
    ASSERT_EQ(first_difference(p, back), "") << yaml;
    ASSERT_EQ(ci::parameters_to_yaml(back), yaml);
  }
}

}  // namespace

TEST(YamlConfig, CommaOutsideAListOrMapIsRejectedNotLoopedOn) {
  // yaml-cpp 0.7's LoadAll never returned on these (an endless run of empty documents until
  // memory ran out); the loader parses at most two documents.
  for (const std::string yaml : {",", ", a", "  ,", ",,", "# a comment\n,", "\t,", "\"a\",", "'a',",
                                 "[1],", "{a: 1},", "\"a\"\n,", "\xef\xbb\xbf,"}) {
    EXPECT_TRUE(
        yaml_rejected_with(yaml, {"test.yaml:", "malformed YAML: ',' outside a list or map"}))
        << yaml;
  }
  // A comma inside a value or a flow collection is still fine where YAML allows it.
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  translation: [1, 2,]\n",
                                 {"stiffness.translation must be 3 numbers"}));
}
