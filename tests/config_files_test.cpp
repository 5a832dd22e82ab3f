// The repository's files that come from the parameter table: the example parameter files load and
// run a controller, and the README's parameter table is current.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include <map>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "support/validation_harness.hpp"

namespace ci = cartesian_impedance;
using namespace validation_harness;

namespace {

// ---------------------------------------------------------------------------------------------
// The example parameter files

std::string source_path(const std::string& relative) {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/" + relative;
}

/// Dotted keys of every leaf in a block-style YAML file (the style of config/*.yaml).
std::set<std::string> leaf_keys(const std::string& path) {
  std::ifstream file(path);
  std::set<std::string> keys;
  std::vector<std::pair<std::size_t, std::string>> parents;  // (indent, key)
  for (std::string line; std::getline(file, line);) {
    const std::size_t comment = line.find('#');
    if (comment != std::string::npos) line.erase(comment);
    const std::size_t indent = line.find_first_not_of(' ');
    const std::size_t colon = line.find(':');
    if (indent == std::string::npos || colon == std::string::npos) continue;
    while (!parents.empty() && parents.back().first >= indent) parents.pop_back();
    std::string key;
    for (const auto& parent : parents) key += parent.second + ".";
    key += line.substr(indent, colon - indent);
    if (line.find_first_not_of(' ', colon + 1) == std::string::npos) {
      parents.emplace_back(indent, line.substr(indent, colon - indent));
    } else {
      keys.insert(key);
    }
  }
  return keys;
}

void expect_example_file(const std::string& relative, const ci::JointVector& torque_limits) {
  SCOPED_TRACE(relative);
  const std::string path = source_path(relative);
  ci::Parameters p;
  ASSERT_NO_THROW(p = ci::load_parameters(path));
  EXPECT_TRUE(same_bits(ci::per_joint(p.limits.joint_torque, kJoints), torque_limits));

  // Every row of the table is set in the file, so it documents every parameter.
  const std::set<std::string> keys = leaf_keys(path);
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    EXPECT_EQ(keys.count(std::string(info.name)), 1u) << info.name << " is not set in " << path;
  }

  // A 7-joint controller runs on it; the torque stays within the robot's limits.
  std::unique_ptr<ci::CartesianImpedanceController> controller;
  ASSERT_NO_THROW(controller = std::make_unique<ci::CartesianImpedanceController>(kJoints, p));
  EXPECT_THROW(ci::CartesianImpedanceController(6, p), ci::Error) << "limits are per joint";
  const ci::RobotState robot = rig_robot();
  controller->start(robot);
  ci::Pose reference = robot.pose;
  reference.position.x() += 0.05;
  controller->set_reference_pose(reference);
  for (int cycle = 0; cycle < 500; ++cycle) {
    ASSERT_EQ(controller->update(robot, kDt), ci::Status::ok);
    for (Eigen::Index i = 0; i < kJoints; ++i) {
      ASSERT_LE(std::abs(controller->torque()[i]), torque_limits[i]);
    }
  }
  EXPECT_GT(controller->torque().cwiseAbs().maxCoeff(), 0.0);
}

TEST(ConfigFiles, PandaLoadsAndRunsASevenJointController) {
  expect_example_file("config/panda.yaml", joints({87, 87, 87, 87, 12, 12, 12}));
  const ci::Parameters p = ci::load_parameters(source_path("config/panda.yaml"));
  EXPECT_TRUE(same_bits(ci::per_joint(p.limits.joint_torque_rate, kJoints),
                        ci::JointVector::Constant(kJoints, 1000)));
}

TEST(ConfigFiles, Iiwa14LoadsAndRunsASevenJointController) {
  expect_example_file("config/iiwa14.yaml", joints({320, 320, 176, 176, 110, 40, 40}));
}

// Every number of a YAML document by its dotted key (list elements as key[i]), as written.
void collect_numbers(const YAML::Node& node, const std::string& key,
                     std::map<std::string, std::string>& numbers) {
  if (node.IsMap()) {
    for (const auto& member : node) {
      const std::string name = member.first.as<std::string>();
      collect_numbers(member.second, key.empty() ? name : key + "." + name, numbers);
    }
  } else if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) {
      collect_numbers(node[i], key + "[" + std::to_string(i) + "]", numbers);
    }
  } else if (node.IsScalar()) {
    const std::string& text = node.Scalar();
    char* end = nullptr;
    std::strtod(text.c_str(), &end);
    if (!text.empty() && end == text.c_str() + text.size()) numbers[key] = text;
  }
}

std::map<std::string, std::string> numbers_of(const std::string& yaml) {
  std::map<std::string, std::string> numbers;
  collect_numbers(YAML::Load(yaml), "", numbers);
  return numbers;
}

// A number as a person writes it, without a redundant fraction: "1.0" -> "1", "0.50" -> "0.5".
std::string without_trailing_zeros(std::string text) {
  if (text.find('.') == std::string::npos || text.find_first_of("eE") != std::string::npos) {
    return text;
  }
  while (text.back() == '0') text.pop_back();
  if (text.back() == '.') text.pop_back();
  return text;
}

// Written back, every shipped configuration shows the numbers its author wrote (0.2, not
// 0.20000000000000001), each the shortest text that reads back as the same double, and reads
// back to the same parameters.
TEST(ConfigFiles, WrittenBackKeepTheNumbersAsWritten) {
  for (const char* relative :
       {"config/panda.yaml", "config/iiwa14.yaml", "config/ur5e.yaml", "config/planar3.yaml"}) {
    SCOPED_TRACE(relative);
    std::ifstream file(source_path(relative));
    std::stringstream text;
    text << file.rdbuf();
    const std::map<std::string, std::string> given = numbers_of(text.str());
    ASSERT_GT(given.size(), 20u);
    const std::string written = ci::parameters_to_yaml(ci::load_parameters(source_path(relative)));
    const std::map<std::string, std::string> numbers = numbers_of(written);
    for (const auto& [key, user_text] : given) {
      // A value given once for all axes or joints is written once per axis or joint.
      const auto found = numbers.find(key);
      if (found != numbers.end()) {
        EXPECT_EQ(found->second, without_trailing_zeros(user_text)) << key;
      } else {
        ASSERT_EQ(numbers.count(key + "[0]"), 1u) << key << " is not in\n" << written;
        for (int i = 0; numbers.count(key + "[" + std::to_string(i) + "]") != 0; ++i) {
          EXPECT_EQ(numbers.at(key + "[" + std::to_string(i) + "]"),
                    without_trailing_zeros(user_text))
              << key << "[" << i << "]";
        }
      }
    }
    for (const auto& [key, written_text] : numbers) {
      EXPECT_EQ(ci::format_exact(std::strtod(written_text.c_str(), nullptr)), written_text) << key;
    }
    EXPECT_EQ(ci::parameters_to_yaml(ci::parameters_from_yaml(written)), written);
  }
}

// The two number formats: messages round to 10 significant digits; files write the shortest text
// that reads back exactly.
TEST(Numbers, MessagesRoundAndFilesKeepEveryBit) {
  EXPECT_EQ(ci::format_number(0.1 + 0.2), "0.3");
  EXPECT_EQ(ci::format_number(2.0 * M_PI), "6.283185307");
  EXPECT_EQ(ci::format_number(1e9), "1000000000");
  EXPECT_EQ(ci::format_number(std::nan("")), "nan");
  EXPECT_EQ(ci::format_number(-HUGE_VAL), "-inf");
  EXPECT_EQ(ci::format_exact(0.2), "0.2");
  EXPECT_EQ(ci::format_exact(0.1 + 0.2), "0.30000000000000004");
  EXPECT_EQ(ci::format_exact(0.00001), "0.00001");
  EXPECT_EQ(ci::format_exact(5000.0), "5000");
  EXPECT_EQ(ci::format_exact(1e-12), "1e-12");
  EXPECT_EQ(ci::format_exact(-0.0698), "-0.0698");
  std::mt19937_64 rng(28);
  std::uniform_real_distribution<double> exponent(-30.0, 30.0), mantissa(-1.0, 1.0);
  for (int i = 0; i < 10000; ++i) {
    const double value = mantissa(rng) * std::pow(10.0, exponent(rng));
    const std::string text = ci::format_exact(value);
    EXPECT_EQ(std::strtod(text.c_str(), nullptr), value) << text;
    EXPECT_LE(text.size(), 24u) << text;
  }
}

// ---------------------------------------------------------------------------------------------
// README parameter table

constexpr std::string_view kBeginMarker = "<!-- parameters:begin -->";
constexpr std::string_view kEndMarker = "<!-- parameters:end -->";
constexpr const char* kRegenerate =
    "UPDATE_README=1 build/tests/core_tests --gtest_filter='Readme*'";

/// Byte range of the text between the begin-marker line and the end-marker line.
struct Section {
  std::size_t begin;
  std::size_t end;
};

/// Finds the lines that are exactly the markers; nullopt if either is missing or out of order.
std::optional<Section> parameter_section(const std::string& text) {
  std::optional<std::size_t> content_begin;
  for (std::size_t line_begin = 0; line_begin < text.size();) {
    std::size_t line_end = text.find('\n', line_begin);
    if (line_end == std::string::npos) line_end = text.size();
    std::string_view line(text.data() + line_begin, line_end - line_begin);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (!content_begin && line == kBeginMarker) {
      content_begin = std::min(line_end + 1, text.size());
    } else if (content_begin && line == kEndMarker) {
      return Section{*content_begin, line_begin};
    }
    line_begin = line_end + 1;
  }
  return std::nullopt;
}

std::string with_section_replaced(const std::string& text, const Section& section,
                                  const std::string& table) {
  return text.substr(0, section.begin) + table + text.substr(section.end);
}

/// README.md of the repository; CARTESIAN_IMPEDANCE_README points elsewhere (e.g. a scratch copy).
std::string readme_path() {
  const char* overridden = std::getenv("CARTESIAN_IMPEDANCE_README");
  return overridden != nullptr ? overridden : source_path("README.md");
}

TEST(Readme, ParameterTableIsCurrent) {
  const std::string path = readme_path();
  std::ifstream file(path);
  ASSERT_TRUE(file) << "cannot read " << path;
  std::stringstream buffer;
  buffer << file.rdbuf();
  const std::string text = buffer.str();
  const std::optional<Section> section = parameter_section(text);
  ASSERT_TRUE(section) << path << " needs a line '" << kBeginMarker
                       << "' followed later by a line '" << kEndMarker << "'; then run\n  "
                       << kRegenerate;
  const std::string expected = ci::parameter_table_markdown();
  const std::string actual = text.substr(section->begin, section->end - section->begin);
  if (actual == expected) return;

  const char* update = std::getenv("UPDATE_README");
  if (update != nullptr && std::string(update) == "1") {
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        << with_section_replaced(text, *section, expected);
    std::printf("Updated the parameter table in %s\n", path.c_str());
    return;
  }
  ADD_FAILURE() << "The parameter table in " << path
                << " is out of date. Between the markers it should read:\n"
                << expected << "\nRegenerate it with:\n  " << kRegenerate;
}

TEST(Readme, SectionIsFoundAndReplacedLeavingTheRestAlone) {
  const std::string text =
      "# Title\n\nintro\n<!-- parameters:begin -->\nold table\n<!-- parameters:end -->\nafter\n";
  const std::optional<Section> section = parameter_section(text);
  ASSERT_TRUE(section);
  EXPECT_EQ(text.substr(section->begin, section->end - section->begin), "old table\n");
  EXPECT_EQ(with_section_replaced(text, *section, "| new |\n"),
            "# Title\n\nintro\n<!-- parameters:begin -->\n| new |\n<!-- parameters:end -->\n"
            "after\n");

  const std::optional<Section> empty =
      parameter_section("<!-- parameters:begin -->\n<!-- parameters:end -->\n");
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->begin, empty->end);
  EXPECT_FALSE(parameter_section("no markers\n"));
  EXPECT_FALSE(parameter_section("<!-- parameters:end -->\n<!-- parameters:begin -->\n"));
  EXPECT_FALSE(
      parameter_section("see <!-- parameters:begin --> inline\n<!-- parameters:end -->\n"));
}

}  // namespace
