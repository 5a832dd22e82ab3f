// Load-time errors of the robot model: missing or malformed files, unknown links, chains it cannot
// model, bad numbers, malformed trees. Each is rejected with a cartesian_impedance::Error that
// names the culprit.

#include <console_bridge/console.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "support/fifo.hpp"
#include "support/model_fixtures.hpp"

namespace ci = cartesian_impedance;
using namespace model_fixtures;

namespace {

// The message of the ci::Error that `load` throws, or a note that it threw something else.
std::string error_of(const std::function<void()>& load) {
  try {
    load();
  } catch (const ci::Error& error) {
    return error.what();
  } catch (const std::exception& other) {
    return std::string("<not a cartesian_impedance::Error: ") + other.what() + ">";
  }
  return "<no exception>";
}

void expect_contains(const std::string& message, std::initializer_list<std::string> parts) {
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos)
        << "expected \"" << part << "\" in the message: " << message;
  }
}

// A serial robot l0 - j1 - l1 - ... - jk - lk with the given joint types, each link 1 kg, each
// joint 0.1 m above the previous; `extra` is inserted before </robot>.
std::string serial_urdf(const std::vector<std::string>& types, const std::string& extra = "",
                        const std::string& link_inertial =
                            "<inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" "
                            "izz=\"0.01\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>") {
  std::ostringstream xml;
  xml << "<robot name=\"serial\">\n<link name=\"l0\"/>\n";
  for (std::size_t i = 1; i <= types.size(); ++i) {
    xml << "<link name=\"l" << i << "\">" << link_inertial << "</link>\n";
    xml << "<joint name=\"j" << i << "\" type=\"" << types[i - 1] << "\"><parent link=\"l" << i - 1
        << "\"/><child link=\"l" << i << "\"/><origin xyz=\"0 0 0.1\"/><axis xyz=\"0 0 1\"/>";
    if (types[i - 1] == "revolute" || types[i - 1] == "prismatic") {
      xml << "<limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"10\"/>";
    }
    xml << "</joint>\n";
  }
  xml << extra << "</robot>\n";
  return xml.str();
}

std::string load_error(const std::string& xml, const std::string& base, const std::string& tip) {
  return error_of([&] { ci::RobotModel::from_urdf_string(xml, base, tip); });
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Load-time errors.

TEST(LoadErrors, MissingOrUnreadableFile) {
  const std::string missing = "/nonexistent/robot.urdf";
  expect_contains(error_of([&] { ci::RobotModel::from_urdf_file(missing, "a", "b"); }),
                  {"'/nonexistent/robot.urdf'", "does not exist"});
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(CARTESIAN_IMPEDANCE_SOURCE_DIR, "a", "b"); }),
      {CARTESIAN_IMPEDANCE_SOURCE_DIR, "is a directory"});
}

// What is no regular file is refused before it is opened (core/files.hpp): opening a FIFO waits
// for a writer forever, /dev/zero never ends.
TEST(LoadErrors, FifoAndDeviceAreRefusedBeforeReading) {
  const ci::test::Fifo fifo("model_load_errors");
  expect_contains(error_of([&] { ci::RobotModel::from_urdf_file(fifo.path(), "a", "b"); }),
                  {"URDF file '" + fifo.path() + "' is a FIFO (named pipe), not a regular file"});
  EXPECT_THROW(ci::RobotModel::from_urdf_file(fifo.path(), "a", "b"), ci::LoadError);
  expect_contains(error_of([] { ci::RobotModel::from_urdf_file("/dev/zero", "a", "b"); }),
                  {"URDF file '/dev/zero' is a character device", "not a regular file"});
}

// A bad description is a LoadError (fix the file); a bad argument beside it a plain Error.
TEST(LoadErrors, FileProblemsAreLoadErrorsAndBadArgumentsPlainErrors) {
  EXPECT_THROW(ci::RobotModel::from_urdf_file("/no/such.urdf", "a", "b"), ci::LoadError);
  EXPECT_THROW(ci::RobotModel::from_urdf_string("<robot", "a", "b"), ci::LoadError);
  EXPECT_THROW(ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "gripper"),
               ci::LoadError);
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.translation().x() = std::nan("");
  try {
    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8", tool);
    FAIL() << "a non-finite tool offset must be rejected";
  } catch (const ci::LoadError& error) {
    FAIL() << "a bad argument is not a bad file: " << error.what();
  } catch (const ci::Error&) {
  }
}

TEST(LoadErrors, MalformedXmlOrNotAUrdf) {
  expect_contains(load_error("<robot name='r'><link name='a'/>", "a", "b"),
                  {"the URDF text", "not a valid URDF", "urdfdom says"});
  expect_contains(load_error("", "a", "b"), {"not a valid URDF", "empty"});
  expect_contains(load_error("<html><body/></html>", "a", "b"), {"not a valid URDF", "robot"});
  // urdfdom logs an error for a mass of "nan" but still returns a model (with mass 0); the
  // logged error must count.
  expect_contains(load_error(serial_urdf({"revolute"}, "",
                                         "<inertial><mass value=\"nan\"/><inertia ixx=\"1\" "
                                         "iyy=\"1\" izz=\"1\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"
                                         "</inertial>"),
                             "l0", "l1"),
                  {"not a valid URDF", "nan", "l1"});
  // The file's path is named when the text came from a file.
  const std::string path = ::testing::TempDir() + "/model_test_broken.urdf";
  std::ofstream(path) << "<robot name='r'><link name='a'/>";
  expect_contains(error_of([&] { ci::RobotModel::from_urdf_file(path, "a", "b"); }),
                  {"URDF file '" + path + "'", "not a valid URDF"});
}

TEST(LoadErrors, UrdfdomErrorsAreCaughtEvenWhenItsLogIsSilenced) {
  // An application may silence console_bridge (urdfdom's log); its errors must still count.
  const console_bridge::LogLevel level = console_bridge::getLogLevel();
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  const std::string message = load_error(
      serial_urdf({"revolute"}, "",
                  "<inertial><mass value=\"nan\"/><inertia ixx=\"1\" iyy=\"1\" izz=\"1\" "
                  "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>"),
      "l0", "l1");
  EXPECT_EQ(console_bridge::getLogLevel(), console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  console_bridge::setLogLevel(level);
  expect_contains(message, {"not a valid URDF", "nan"});
}

TEST(LoadErrors, UnknownLinksAreNamedWithTheAvailableOnes) {
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link_0", "panda_link8"); }),
      {"base link 'panda_link_0'", "not a link", "panda", "panda_link0", "panda_link7"});
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_hand"); }),
      {"tip link 'panda_hand'", "not a link", "panda_link8"});
  // Long lists are cut short with a count.
  std::vector<std::string> many(20, "fixed");
  many[0] = "revolute";
  expect_contains(load_error(serial_urdf(many), "l0", "nowhere"), {"'nowhere'", "21 in all"});
}

TEST(LoadErrors, TipMustBeBelowTheBase) {
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link5", "panda_link2"); }),
      {"tip link 'panda_link2'", "above base link 'panda_link5'"});
  // Two branches of one tree: neither is below the other.
  const std::string branched = serial_urdf(
      {"revolute", "revolute"},
      "<link name=\"side\"/><joint name=\"js\" type=\"revolute\"><parent link=\"l0\"/>"
      "<child link=\"side\"/><limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"1\"/>"
      "</joint>\n");
  expect_contains(load_error(branched, "side", "l2"),
                  {"tip link 'l2'", "not below base link 'side'", "l2 <- l1 <- l0"});
  expect_contains(load_error(branched, "l1", "l1"), {"'l1' is the base link", "movable joint"});
}

TEST(LoadErrors, ChainWithoutMovableJoints) {
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link7", "panda_link8"); }),
      {"'panda_link7'", "'panda_link8'", "no movable joint"});
}

TEST(LoadErrors, TooManyJoints) {
  const int too_many = ci::kMaxJoints + 1;
  const std::vector<std::string> joints(too_many, "revolute");
  const std::string tip = "l" + std::to_string(too_many);
  expect_contains(load_error(serial_urdf(joints), "l0", tip),
                  {std::to_string(too_many) + " movable joints",
                   "at most kMaxJoints = " + std::to_string(ci::kMaxJoints)});
  // kMaxJoints are fine, and so are joints beyond the tip.
  EXPECT_EQ(ci::RobotModel::from_urdf_string(serial_urdf(joints), "l0",
                                             "l" + std::to_string(ci::kMaxJoints))
                .num_joints(),
            ci::kMaxJoints);
}

TEST(LoadErrors, UnsupportedJointTypes) {
  expect_contains(load_error(serial_urdf({"revolute", "floating", "revolute"}), "l0", "l3"),
                  {"joint 'j2'", "is floating", "revolute, continuous, prismatic and fixed"});
  expect_contains(load_error(serial_urdf({"planar", "revolute"}), "l0", "l2"),
                  {"joint 'j1'", "is planar"});
  // Outside the chain they do not matter.
  EXPECT_EQ(ci::RobotModel::from_urdf_string(serial_urdf({"revolute", "floating"}), "l0", "l1")
                .num_joints(),
            1);
  const std::string mimic =
      "<robot name=\"m\"><link name=\"a\"/><link name=\"b\"/><link name=\"c\"/>"
      "<joint name=\"j1\" type=\"continuous\"><parent link=\"a\"/><child link=\"b\"/></joint>"
      "<joint name=\"j2\" type=\"continuous\"><parent link=\"b\"/><child link=\"c\"/>"
      "<mimic joint=\"j1\" multiplier=\"1\"/></joint></robot>";
  expect_contains(load_error(mimic, "a", "c"), {"joint 'j2' mimics joint 'j1'", "not supported"});
}

TEST(LoadErrors, BadMassAndInertia) {
  const auto inertial = [](const std::string& mass, const std::string& ixx) {
    return "<inertial><mass value=\"" + mass + "\"/><inertia ixx=\"" + ixx +
           "\" iyy=\"0.01\" izz=\"0.01\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>";
  };
  expect_contains(load_error(serial_urdf({"revolute"}, "", inertial("-1.5", "0.01")), "l0", "l1"),
                  {"link 'l1'", "mass = -1.5 kg", "expected a finite value >= 0"});
  expect_contains(load_error(serial_urdf({"revolute"}, "", inertial("1", "-0.01")), "l0", "l1"),
                  {"link 'l1'", "not positive semi-definite", "-0.01"});
  // A bad mass fixed to a chain link is lumped into it, so it is checked too.
  expect_contains(
      load_error(serial_urdf({"revolute"}, "<link name=\"lump\">" + inertial("-2", "0.01") +
                                               "</link><joint name=\"jl\" type=\"fixed\"><parent "
                                               "link=\"l1\"/><child link=\"lump\"/></joint>"),
                 "l0", "l1"),
      {"link 'lump'", "mass = -2 kg"});
}

TEST(LoadErrors, BadAxisAndLimits) {
  const std::string zero_axis =
      "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><joint name=\"j\" "
      "type=\"continuous\"><parent link=\"a\"/><child link=\"b\"/><axis xyz=\"0 0 0\"/></joint>"
      "</robot>";
  expect_contains(load_error(zero_axis, "a", "b"), {"joint 'j'", "axis = (0, 0, 0)", "non-zero"});
  const auto with_limit = [](const std::string& limit) {
    return "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><joint name=\"j\" "
           "type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>" +
           limit + "</joint></robot>";
  };
  expect_contains(
      load_error(with_limit("<limit lower=\"1\" upper=\"-1\" velocity=\"1\" effort=\"1\"/>"), "a",
                 "b"),
      {"joint 'j'", "position limits [1, -1]", "lower <= upper"});
  expect_contains(
      load_error(with_limit("<limit lower=\"-1\" upper=\"1\" velocity=\"-2\" effort=\"1\"/>"), "a",
                 "b"),
      {"joint 'j'", "velocity limit = -2"});
  expect_contains(
      load_error(with_limit("<limit lower=\"-1\" upper=\"1\" velocity=\"2\" effort=\"-3\"/>"), "a",
                 "b"),
      {"joint 'j'", "effort limit = -3"});
}

TEST(LoadErrors, BadToolOrGravity) {
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 1.1;
  expect_contains(error_of([&] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   scaled);
                  }),
                  {"T_tip_tool", "not a rotation matrix", "0.21"});
  Eigen::Isometry3d mirrored = Eigen::Isometry3d::Identity();
  mirrored.linear() = Eigen::Vector3d(1, 1, -1).asDiagonal();
  expect_contains(error_of([&] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   mirrored);
                  }),
                  {"T_tip_tool", "det R = -1"});
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation().x() = std::numeric_limits<double>::infinity();
  expect_contains(error_of([&] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8", far);
                  }),
                  {"T_tip_tool", "non-finite"});
  expect_contains(error_of([] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   Eigen::Isometry3d::Identity(),
                                                   Eigen::Vector3d(0, std::nan(""), -9.81));
                  }),
                  {"gravity_base = (0, nan, -9.81)", "non-finite"});
}

// ---------------------------------------------------------------------------------------------
// Malformed trees and absurd numbers: the loader fails closed, with the culprits named.

namespace {

// A link of 1 kg and a joint of `type` from `parent` to `child` (URDF snippets for `extra`).
std::string link_xml(const std::string& name) {
  return "<link name=\"" + name +
         "\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.01\" "
         "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>\n";
}
std::string joint_xml(const std::string& name, const std::string& parent, const std::string& child,
                      const std::string& type = "fixed", const std::string& inside = "") {
  return "<joint name=\"" + name + "\" type=\"" + type + "\"><parent link=\"" + parent +
         "\"/><child link=\"" + child + "\"/>" + inside + "</joint>\n";
}

}  // namespace

TEST(LoadErrors, LoopOfLinksNotConnectedToTheRootIsRejected) {
  // x -> y -> z -> x beside the chain l0 -> l1 -> l2: urdfdom finds the root l0 and accepts it.
  const std::string loop = link_xml("x") + link_xml("y") + link_xml("z") +
                           joint_xml("jxy", "x", "y") + joint_xml("jyz", "y", "z") +
                           joint_xml("jzx", "z", "x");
  const std::string xml = serial_urdf({"revolute", "revolute"}, loop);
  // Before, a chain into the loop walked its parents for ever; now any loop is rejected, even
  // one the requested chain does not touch.
  for (const auto& [base, tip] :
       std::vector<std::pair<std::string, std::string>>{{"l0", "l2"}, {"l0", "y"}, {"x", "z"}}) {
    SCOPED_TRACE(base + " -> " + tip);
    expect_contains(load_error(xml, base, tip),
                    {"the URDF text", "loop", "'x'", "'y'", "'z'", "'jxy'", "'jyz'", "'jzx'"});
  }
}

TEST(LoadErrors, LoopHiddenBehindXmlEntitiesIsRejectedAfterParsing) {
  // The pre-parse check compares names as written, so "&#120;" (an 'x' in XML) escapes it;
  // the check on urdfdom's own model must still catch the loop.
  const std::string loop =
      link_xml("x") + link_xml("y") + joint_xml("jxy", "x", "y") + joint_xml("jyx", "y", "&#120;");
  expect_contains(load_error(serial_urdf({"revolute"}, loop), "l0", "y"),
                  {"loop", "'x'", "'y'", "'jxy'", "'jyx'"});
}

TEST(LoadErrors, LongFixedSideBranchIsLumpedWithoutRecursion) {
  // 10,000 links of 1 g in a row, fixed to l1: before, lumping them recursed once per link and
  // overflowed the stack.
  constexpr int kLinks = 10000;
  std::string branch;
  branch.reserve(kLinks * 260);
  for (int i = 0; i < kLinks; ++i) {
    const std::string name = "b" + std::to_string(i);
    branch += "<link name=\"" + name +
              "\"><inertial><mass value=\"0.001\"/><inertia ixx=\"0\" iyy=\"0\" izz=\"0\" "
              "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>" +
              joint_xml("jb" + std::to_string(i), i == 0 ? "l1" : "b" + std::to_string(i - 1), name,
                        "fixed", "<origin xyz=\"0.001 0 0\"/>");
  }
  const ci::RobotModel model =
      ci::RobotModel::from_urdf_string(serial_urdf({"revolute"}, branch), "l0", "l1");
  EXPECT_NEAR(model.moving_mass(), 1.0 + kLinks * 0.001, 1e-9);
}

TEST(LoadErrors, DeeplyNestedXmlIsRejectedBeforeUrdfdomRecursesIntoIt) {
  // TinyXML (under urdfdom) parses nested elements recursively: 100,000 levels overflowed the
  // stack. The nesting is checked on the text first.
  constexpr int kDepth = 100000;
  std::string deep;
  deep.reserve(kDepth * 7);
  for (int i = 0; i < kDepth; ++i) deep += "<a>";
  for (int i = 0; i < kDepth; ++i) deep += "</a>";
  const std::string xml = serial_urdf({"revolute"}, "<link name=\"deep\">\n" + deep + "</link>\n");
  expect_contains(load_error(xml, "l0", "l1"),
                  {"the URDF text", "nests XML elements more than 100 deep", "line"});
  // Ordinary nesting (gazebo extensions and the like) is fine.
  std::string nested;
  for (int i = 0; i < 50; ++i) nested += "<a x='>'>";
  for (int i = 0; i < 50; ++i) nested += "</a>";
  EXPECT_EQ(ci::RobotModel::from_urdf_string(
                serial_urdf({"revolute"}, "<gazebo>" + nested + "</gazebo>\n"), "l0", "l1")
                .num_joints(),
            1);
}

TEST(LoadErrors, TextThatTinyXmlCouldReadDifferentlyFromTheDepthCheckIsRejected) {
  // The depth check reads the text as TinyXML does. Where their readings could part (an XML
  // declaration other than a plain first one, invalid UTF-8 whose lead byte TinyXML takes to
  // swallow a '<', a NUL that ends TinyXML's text early), the text is rejected.
  const std::string serial = serial_urdf({"revolute"});
  expect_contains(load_error(serial + "<?xml version=\"1.0\"?>", "l0", "l1"),
                  {"XML declaration", "line 6", "only come first"});
  expect_contains(load_error("<?xml version=\"<a>\"?>" + serial, "l0", "l1"),
                  {"XML declaration", "line 1"});
  expect_contains(load_error(serial_urdf({"revolute"}, "<!-- \xF0 -->"), "l0", "l1"),
                  {"not valid UTF-8", "line 5"});
  expect_contains(load_error(serial + std::string(1, '\0') + "<robot/>", "l0", "l1"),
                  {"NUL", "line 6"});
  expect_contains(
      load_error(serial_urdf({"revolute"}, "<a b=\xEF\xBB\xBF\"</robot>\"/>"), "l0", "l1"),
      {"U+FEFF", "line 5"});
  // What would take TinyXML quadratic time: "&#" without a ';' close by, many attributes.
  expect_contains(load_error(serial_urdf({"revolute"}, "<!-- &#x1 -->"), "l0", "l1"),
                  {"character reference", "line 5"});
  std::string attributes = "<a";
  for (int i = 0; i < 65; ++i) attributes += " a" + std::to_string(i) + "='1'";
  expect_contains(load_error(serial_urdf({"revolute"}, attributes + "/>"), "l0", "l1"),
                  {"more than 64 attributes", "line 5"});
  // Unclosed constructs, which older TinyXML versions read past the end of the text.
  for (const char* tail : {"<!-- ", "<![CDATA[ ", "<link name=\"x", "<link ", "<!DOCTYPE"}) {
    expect_contains(load_error(serial + tail, "l0", "l1"), {"never closed", "line 6"});
  }
  // A plain declaration, comments, CDATA and UTF-8 names are fine.
  const std::string fine = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- <a><a><a> -->" +
                           serial_urdf({"revolute"},
                                       "<link name=\"gr\xC3\xBC\xC3\x9F\">"
                                       "<![CDATA[<a><a>]]></link>" +
                                           joint_xml("to_gruss", "l1", "gr\xC3\xBC\xC3\x9F"));
  EXPECT_EQ(ci::RobotModel::from_urdf_string(fine, "l0", "l1").num_joints(), 1);
}

TEST(LoadErrors, LinkWithTwoParentJointsIsRejected) {
  // urdfdom keeps one of the two parents (the last it reads) and says nothing.
  const std::string xml =
      serial_urdf({"revolute", "revolute"}, link_xml("c") + joint_xml("to_c_from_l1", "l1", "c") +
                                                joint_xml("to_c_from_l2", "l2", "c"));
  expect_contains(load_error(xml, "l0", "c"), {"link 'c'", "two parent joints", "'to_c_from_l1'",
                                               "'to_c_from_l2'", "'l1'", "'l2'"});
}

TEST(LoadErrors, JointFromALinkToItselfIsRejected) {
  const std::string xml = serial_urdf({"revolute"}, joint_xml("self", "l1", "l1", "continuous"));
  expect_contains(load_error(xml, "l0", "l1"),
                  {"joint 'self'", "link 'l1'", "both its parent and its child"});
}

TEST(LoadErrors, AbsurdNumbersAreRejectedAtLoadTime) {
  // Before, each of these loaded, and then every control cycle failed with numerical_error.
  const auto one_joint = [](const std::string& origin, const std::string& axis,
                            const std::string& type = "revolute",
                            const std::string& limit =
                                "<limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"1\"/>") {
    return "<robot name=\"r\"><link name=\"a\"/>" + link_xml("b") +
           joint_xml("j", "a", "b", type,
                     "<origin xyz=\"" + origin + "\"/><axis xyz=\"" + axis + "\"/>" + limit) +
           "</robot>";
  };
  expect_contains(load_error(one_joint("1e308 0 0", "0 0 1"), "a", "b"),
                  {"joint 'j'", "origin xyz = (1e+308, 0, 0)", "1000 m"});
  expect_contains(load_error(one_joint("0 0 -1000.5", "0 0 1"), "a", "b"),
                  {"joint 'j'", "-1000.5", "1000 m"});
  // The norm is computed without overflow, and a direction may have a norm of 5, not of 1e308.
  expect_contains(
      load_error(one_joint("0 0 0", "1e308 1e308 1e308"), "a", "b"),
      {"joint 'j'", "axis = (1e+308, 1e+308, 1e+308)", "norm 1.73205e+308", "[1e-09, 1e+09]"});
  expect_contains(load_error(one_joint("0 0 0", "1.5e308 1.5e308 0"), "a", "b"),
                  {"joint 'j'", "norm inf", "[1e-09, 1e+09]"});
  expect_contains(load_error(one_joint("0 0 0", "1e-12 0 0"), "a", "b"),
                  {"joint 'j'", "axis = (1e-12, 0, 0)", "norm 1e-12", "[1e-09, 1e+09]"});
  expect_contains(
      load_error(one_joint("0 0 0", "1 0 0", "prismatic",
                           "<limit lower=\"-1e308\" upper=\"1\" velocity=\"1\" effort=\"1\"/>"),
                 "a", "b"),
      {"joint 'j'", "position limits [-1e+308, 1]", "1000 m"});
  const auto with_inertial = [](const std::string& inertial) {
    return serial_urdf({"revolute"}, "", "<inertial>" + inertial + "</inertial>");
  };
  expect_contains(load_error(with_inertial("<mass value=\"1e7\"/><inertia ixx=\"1\" iyy=\"1\" "
                                           "izz=\"1\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
                             "l0", "l1"),
                  {"link 'l1'", "mass = 1e+07 kg", "1e+06 kg"});
  expect_contains(
      load_error(with_inertial("<mass value=\"1\"/><inertia ixx=\"1e308\" iyy=\"1e308\" "
                               "izz=\"1e308\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
                 "l0", "l1"),
      {"link 'l1'", "inertia", "1e+308", "1e+06 kg m^2"});
  expect_contains(
      load_error(with_inertial("<origin xyz=\"0 1e308 0\"/><mass value=\"1\"/><inertia ixx=\"1\" "
                               "iyy=\"1\" izz=\"1\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
                 "l0", "l1"),
      {"link 'l1'", "inertial origin xyz = (0, 1e+308, 0)", "1000 m"});
  // The bounds themselves are valid.
  EXPECT_NO_THROW(ci::RobotModel::from_urdf_string(one_joint("1000 -1000 0", "0 0 5"), "a", "b"));
  EXPECT_NO_THROW(ci::RobotModel::from_urdf_string(
      with_inertial("<origin xyz=\"0 -1000 0\"/><mass value=\"1e6\"/><inertia ixx=\"1e6\" "
                    "iyy=\"1e6\" izz=\"1e6\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
      "l0", "l1"));
}

TEST(LoadErrors, ModelThatCannotBeEvaluatedAtZeroIsRejected) {
  // Every number of the file within its bounds, and yet the model must compute: the loader
  // evaluates it once. A gravity of 1e308 m/s^2 is finite, its torques are not.
  expect_contains(error_of([] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   Eigen::Isometry3d::Identity(),
                                                   Eigen::Vector3d(0, 0, -1e308));
                  }),
                  {"URDF file", "gravity", "not finite at q = 0"});
}
