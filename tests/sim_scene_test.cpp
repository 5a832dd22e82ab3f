// The simulation's scenes: robots loaded from their URDF alone (MuJoCo's importer completed
// with rotor inertia, a floor and a sky), load errors, and offscreen rendering with what the
// demo's pictures draw on top of the scene (caption, force arrows, reference frames, a ghost).

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "src/sim/simulation_impl.hpp"
#include "support/sim_reference.hpp"

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
using ci::JointVector;
using ci::Vector6d;
using namespace sim_test;

// ---------------------------------------------------------------------------------------------
// URDF

TEST(Urdf, LoadsSevenJointsAndAppliesTorqueThroughQfrcApplied) {
  for (const std::string& file : {kPandaUrdf, kIiwaUrdf}) {
    SCOPED_TRACE(file);
    const sim::Simulation s = sim::Simulation::from_urdf_file(file);
    EXPECT_EQ(s.num_joints(), 7);
    EXPECT_EQ(s.timestep(), 0.001);
    EXPECT_EQ(s.q(), JointVector::Zero(7));               // URDF has no keyframe
    EXPECT_TRUE(std::isinf(s.torque_upper_limits()[0]));  // no actuator, no limit
  }
  // Without the import's rotor inertia the simulation is MuJoCo's plain URDF model, which the
  // reference loads.
  sim::SimulationOptions options;
  options.armature = JointVector::Zero(1);
  sim::Simulation s = sim::Simulation::from_urdf_file(kPandaUrdf, options);
  EXPECT_EQ(s.joint_names()[3], "panda_joint4");
  s.set_state(panda_ready(), JointVector::Zero(7));
  for (int k = 0; k < 500; ++k) s.step();  // gravity compensation through qfrc_applied
  EXPECT_LT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-3);

  // The reference loads the MJCF the import made (armature 0, as the options above).
  const std::string imported = ::testing::TempDir() + "sim_test_panda_imported.xml";
  std::ofstream(imported) << sim::detail::mjcf_from_urdf(kPandaUrdf, {0.0, 0.5});
  Reference reference(imported);
  std::remove(imported.c_str());
  reference.set_state(s.q(), JointVector::Zero(7));
  s.set_state(s.q(), JointVector::Zero(7));
  const JointVector tau = joints({0, 0, 0, 500, 0, 0, 0});
  EXPECT_FALSE(s.set_torque(tau));  // not limited
  s.step();
  expect_one_step(s.dq(), predict_one_step(reference, tau));
  EXPECT_GT(s.dq()[3], 0.0);
}

TEST(Options, StartConfigurationAndArmatureReplaceTheModels) {
  sim::SimulationOptions options;
  options.start_q = panda_ready();
  sim::Simulation s = sim::Simulation::from_urdf_file(kPandaUrdf, options);
  EXPECT_EQ(s.q(), panda_ready());
  EXPECT_EQ(s.armature(), JointVector::Constant(7, 0.1));  // the URDF import's default
  s.set_state(JointVector::Zero(7), JointVector::Zero(7));
  s.reset();
  EXPECT_EQ(s.q(), panda_ready());  // reset() returns to the start configuration too

  // One torque on the wrist (joint 7, M_77 about 0.01 kg m^2) meets the rotor inertia first:
  // with 1 kg m^2 instead of 0.1 the first step's acceleration is (M_77 + 0.1) / (M_77 + 1),
  // about a ninth; the other joints' coupling moves that by a few per cent at most.
  const JointVector tau = joints({0, 0, 0, 0, 0, 0, 1});
  s.set_torque(tau);
  s.step();
  const double light = s.dq()[6];
  options.armature = JointVector::Constant(1, 1.0);
  sim::Simulation heavy = sim::Simulation::from_urdf_file(kPandaUrdf, options);
  EXPECT_EQ(heavy.armature(), JointVector::Constant(7, 1.0));
  heavy.set_torque(tau);
  heavy.step();
  EXPECT_GT(light, 0.0);
  EXPECT_NEAR(heavy.dq()[6] / light, 0.11 / 1.01, 0.02);

  // Per joint, on an MJCF: replaces the file's values.
  options.armature = joints({0.5, 0.5, 0.5, 0.5, 0.2, 0.2, 0.2});
  options.start_q = JointVector();
  EXPECT_EQ(sim::Simulation::from_mjcf_file(kPandaXml, options).armature(), options.armature);
}

TEST(Errors, BadStartConfigurationOrArmatureNameTheJoint) {
  sim::SimulationOptions options;
  options.start_q = JointVector::Zero(7);  // joint 4's range is [-3.0718, -0.0698]
  EXPECT_ERROR([&] { sim::Simulation::from_urdf_file(kPandaUrdf, options); },
               {"start_q[3] = 0", "panda_joint4", "outside its range [-3.0718, -0.0698]"});
  options.start_q = JointVector::Zero(3);
  EXPECT_ERROR([&] { sim::Simulation::from_urdf_file(kPandaUrdf, options); },
               {"start_q has 3 values", "one per joint (7)"});
  options.start_q = panda_ready();
  options.start_q[1] = std::nan("");
  EXPECT_ERROR([&] { sim::Simulation::from_urdf_file(kPandaUrdf, options); },
               {"start_q[1]", "panda_joint2", "not finite"});
  options.start_q = JointVector();
  options.armature = joints({0.1, 0.1, -0.1, 0.1, 0.1, 0.1, 0.1});
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"armature[2] = -0.1", "panda_joint3", ">= 0"});
  options.armature = JointVector::Constant(2, 0.1);
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"armature has 2 values", "1 or one per joint (7)"});
}

// The URDF-only robots (models/README.md): loaded by MuJoCo's importer, their start configuration
// held by gravity compensation, and the project's model (urdfdom + KDL) of the same file agreeing
// with MuJoCo on the flange pose, the gravity torques and the mass matrix.
namespace {

struct UrdfRobot {
  std::string file;
  std::vector<std::string> joint_names;
  JointVector start;
};

std::vector<UrdfRobot> urdf_robots() {
  return {{kUr5eUrdf,
           {"shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
            "wrist_2_joint", "wrist_3_joint"},
           joints({kPi, -kPi / 2, kPi / 2, -kPi / 2, -kPi / 2, 0})},
          {kPlanar3Urdf, {"joint1", "joint2", "joint3"}, joints({0.5, 1.5, kPi - 2.0})}};
}

}  // namespace

TEST(Urdf, Ur5eAndPlanarArmHoldTheirStartConfigurationWithZeroTorque) {
  for (const UrdfRobot& robot : urdf_robots()) {
    SCOPED_TRACE(robot.file);
    sim::Simulation s = sim::Simulation::from_urdf_file(robot.file);
    EXPECT_EQ(s.joint_names(), robot.joint_names);
    const int n = s.num_joints();
    s.set_state(robot.start, JointVector::Zero(n));
    const ci::Pose start = s.body_pose("tool0");
    // The flange body is the model's tip link at the same q.
    const ci::RobotModel model = ci::RobotModel::from_urdf_file(robot.file, "base_link", "tool0");
    ci::ModelWorkspace workspace(model);
    ci::Pose expected;
    ASSERT_TRUE(workspace.compute_pose(robot.start, expected));
    EXPECT_LT((start.position - expected.position).norm(), 1e-12);
    EXPECT_LT(start.orientation.angularDistance(expected.orientation), 1e-12);
    // Zero torque for 1 s; gravity compensation (on by default) holds the arm (measured: the
    // flange does not move at all; joint friction holds the round-off residues).
    double drift = 0.0;
    for (int k = 0; k < 1000; ++k) {
      s.step();
      drift = std::max(drift, (s.body_pose("tool0").position - start.position).norm());
    }
    EXPECT_NEAR(s.time(), 1.0, 1e-9);
    EXPECT_LT(drift, 1e-3);
    EXPECT_LT((s.q() - robot.start).cwiseAbs().maxCoeff(), 1e-3);
  }
}

TEST(Urdf, Ur5eAndPlanarArmModelGravityAndMassMatchMujoco) {
  for (const UrdfRobot& robot : urdf_robots()) {
    SCOPED_TRACE(robot.file);
    const ci::RobotModel model = ci::RobotModel::from_urdf_file(robot.file, "base_link", "tool0");
    ci::ModelWorkspace workspace(model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    const int n = model.num_joints();
    // Raw MuJoCo on the same URDF (no armature): g(q) and M(q) at random configurations. Measured:
    // 4e-14 Nm and 5e-15 kg m^2. (The Panda's mass matrix agrees only to 1e-8, models/README.md:
    // MuJoCo re-derives each body inertia from an eigen-decomposition; these inertias are nearly
    // diagonal, so it is exact to round-off here.)
    Reference reference(robot.file);
    ASSERT_EQ(reference.nv(), n);
    std::mt19937 rng(21);
    double gravity_error = 0.0, mass_error = 0.0;
    for (int k = 0; k < 100; ++k) {
      JointVector q(n);
      for (int i = 0; i < n; ++i) q[i] = std::uniform_real_distribution<double>(-2.5, 2.5)(rng);
      ASSERT_TRUE(workspace.compute(q, JointVector::Zero(n), kinematics, true));
      reference.set_state(q, JointVector::Zero(n));
      gravity_error =
          std::max(gravity_error, (kinematics.gravity - reference.gravity()).cwiseAbs().maxCoeff());
      mass_error =
          std::max(mass_error, (kinematics.mass - reference.mass_matrix()).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(gravity_error, 1e-12);
    EXPECT_LT(mass_error, 1e-12);

    // The model's g(q) as the commanded torque, MuJoCo's own compensation off: the arm stays for
    // 1 s (measured: it does not move at all); with zero torque it falls.
    sim::SimulationOptions options;
    options.gravity_compensation = false;
    for (const bool compensate : {true, false}) {
      sim::Simulation s = sim::Simulation::from_urdf_file(robot.file, options);
      s.set_state(robot.start, JointVector::Zero(n));
      const Eigen::Vector3d start = s.body_pose("tool0").position;
      double drift = 0.0;
      for (int k = 0; k < 1000; ++k) {
        ASSERT_TRUE(workspace.compute(s.q(), s.dq(), kinematics, true));
        s.set_torque(compensate ? JointVector(kinematics.gravity) : JointVector::Zero(n));
        s.step();
        drift = std::max(drift, (s.body_pose("tool0").position - start).norm());
      }
      if (compensate) {
        EXPECT_LT(drift, 1e-3);
      } else {
        EXPECT_GT(drift, 0.1);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Errors at load time

TEST(Errors, MissingFile) {
  EXPECT_ERROR([] { sim::Simulation::from_mjcf_file("/nonexistent/robot.xml"); },
               {"MJCF", "/nonexistent/robot.xml", "does not exist"});
  EXPECT_ERROR([] { sim::Simulation::from_urdf_file("/nonexistent/robot.urdf"); },
               {"URDF", "/nonexistent/robot.urdf"});
}

TEST(Errors, MalformedXml) {
  const std::string path = ::testing::TempDir() + "sim_test_malformed.xml";
  {
    std::ofstream file(path);
    file << "<mujoco><worldbody><geom type=\"box\" size=\"1 1 1\"</worldbody></mujoco>";
  }
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(path); }, {"cannot load", path});
  std::remove(path.c_str());
}

TEST(Errors, UnknownOrDuplicateJointNameAndBadOptions) {
  sim::SimulationOptions options;
  options.joint_names = {"panda_joint1", "elbow"};
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"joint_names[1]", "'elbow'", "panda_joint1", "panda_joint7"});
  options.joint_names = {"panda_joint1", "panda_joint1"};
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); }, {"twice"});
  options.joint_names = {};
  options.timestep = 0.0;
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"timestep", "0", "positive"});
}

TEST(Errors, UnknownBodyOrSite) {
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_ERROR([&] { s.site_pose("tcp"); }, {"site 'tcp'", "flange"});
  EXPECT_ERROR([&] { s.body_pose("hand"); }, {"body 'hand'", "panda_link0"});
  EXPECT_ERROR([&] { s.contact_wrench("hand"); }, {"body 'hand'", "panda_link8"});
}

TEST(Errors, RenderArgumentsAreCheckedBeforeAnyOpenGl) {
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_ERROR([&] { s.render_png("/tmp/x.png", 0, 10); }, {"size", "0 x 10"});
  EXPECT_ERROR([&] { s.render_png("/tmp/x.png", 10, 10, "overhead"); },
               {"camera 'overhead'", "(none)"});
  EXPECT_ERROR([&] { s.render_png("", 10, 10); }, {"path"});
}

// ---------------------------------------------------------------------------------------------
// Rendering

namespace {

struct PngInfo {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::set<std::uint32_t> colours;
  std::vector<unsigned char> rgb;  // row by row from the top, 3 bytes a pixel

  const unsigned char* at(int column, int row) const {
    return &rgb[3 * (static_cast<std::size_t>(row) * width + static_cast<std::size_t>(column))];
  }
};

PngInfo read_png(const std::string& path) {
  PngInfo info;
  std::ifstream file(path, std::ios::binary);
  std::vector<unsigned char> header(24);
  file.read(reinterpret_cast<char*>(header.data()), 24);
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (!file || !std::equal(signature, signature + 8, header.begin()) ||
      std::string(header.begin() + 12, header.begin() + 16) != "IHDR") {
    return info;
  }
  auto big_endian = [&](int at) {
    return (std::uint32_t{header[at]} << 24) | (std::uint32_t{header[at + 1]} << 16) |
           (std::uint32_t{header[at + 2]} << 8) | std::uint32_t{header[at + 3]};
  };
  info.width = big_endian(16);
  info.height = big_endian(20);

  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&image, path.c_str()) == 0) return info;
  image.format = PNG_FORMAT_RGB;
  std::vector<unsigned char> pixels(PNG_IMAGE_SIZE(image));
  if (png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr) == 0) return info;
  // The pixels must be the picture the header describes (at() indexes them by its size).
  if (image.width != info.width || image.height != info.height) return PngInfo{};
  for (std::size_t i = 0; i + 2 < pixels.size(); i += 3) {
    info.colours.insert((std::uint32_t{pixels[i]} << 16) | (std::uint32_t{pixels[i + 1]} << 8) |
                        pixels[i + 2]);
  }
  info.rgb = std::move(pixels);
  return info;
}

PngInfo render(const sim::Simulation& s, const sim::RenderOverlay& overlay, int width = 320,
               int height = 240) {
  // One file per test and process: ctest runs these tests in parallel processes, which must not
  // read each other's half-written pictures.
  const std::string path = ::testing::TempDir() + "sim_scene_test_render_" +
                           ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
                           std::to_string(::getpid()) + ".png";
  s.render_png(path, width, height, overlay);
  PngInfo info = read_png(path);
  std::remove(path.c_str());
  return info;
}

// Pixels of a saturated colour that the scene itself never has (the robots are white and grey,
// the floor grey-blue, the sky pale blue): magenta, red, green, blue, cyan, yellow by `hue`.
bool is_hue(const unsigned char* p, char hue) {
  const int r = p[0], g = p[1], b = p[2];
  switch (hue) {
    case 'm':
      return r > 120 && b > 120 && g < 0.5 * std::min(r, b);
    case 'r':
      return r > 120 && g < 0.5 * r && b < 0.5 * r;
    case 'g':
      return g > 90 && r < 0.6 * g && b < 0.6 * g;
    case 'b':
      return b > 120 && r < 0.4 * b && g < 0.6 * b;
    case 'c':
      return g > 120 && b > 120 && r < 0.5 * std::min(g, b);
    case 'y':
      return r > 120 && g > 120 && b < 0.5 * std::min(r, g);
  }
  return false;
}

struct Blob {
  int count = 0;
  double column = 0.0;  // mean position of the pixels [pixels]
  double row = 0.0;
};
Blob find_hue(const PngInfo& info, char hue) {
  Blob blob;
  for (int row = 0; row < static_cast<int>(info.height); ++row) {
    for (int column = 0; column < static_cast<int>(info.width); ++column) {
      if (!is_hue(info.at(column, row), hue)) continue;
      ++blob.count;
      blob.column += column;
      blob.row += row;
    }
  }
  if (blob.count > 0) {
    blob.column /= blob.count;
    blob.row /= blob.count;
  }
  return blob;
}

int differing_pixels(const PngInfo& a, const PngInfo& b, int left, int top, int right, int bottom) {
  int count = 0;
  for (int row = top; row < bottom; ++row) {
    for (int column = left; column < right; ++column) {
      const unsigned char* p = a.at(column, row);
      const unsigned char* q = b.at(column, row);
      count += std::abs(p[0] - q[0]) + std::abs(p[1] - q[1]) + std::abs(p[2] - q[2]) > 30 ? 1 : 0;
    }
  }
  return count;
}

double brightness(const unsigned char* p) {
  return (p[0] + p[1] + p[2]) / 3.0;
}

}  // namespace

TEST(Rendering, WritesAPngOfTheRequestedSizeShowingTheScene) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  sim::Simulation s =
      sim::make_scene(kPandaXml, {sim::Box::table({0.45, 0.0}, {0.25, 0.4}, 0.55, "table")});
  const std::string path = ::testing::TempDir() + "sim_test_render.png";
  s.render_png(path, 320, 200);
  PngInfo info = read_png(path);
  EXPECT_EQ(info.width, 320u);
  EXPECT_EQ(info.height, 200u);
  // Floor checker, robot, table, lighting: many colours (a blank frame has one).
  EXPECT_GT(info.colours.size(), 50u);

  // Larger than MuJoCo's default 640 x 480 offscreen buffer: the context grows.
  s.render_png(path, 1000, 700);
  info = read_png(path);
  EXPECT_EQ(info.width, 1000u);
  EXPECT_EQ(info.height, 700u);
  EXPECT_GT(info.colours.size(), 50u);
  std::remove(path.c_str());

  EXPECT_ERROR([&] { s.render_png("/nonexistent/dir/x.png", 10, 10); }, {"/nonexistent/dir/x.png"});
}

TEST(Rendering, SkyIsBrightForTheShippedModelsAndForAModelWithoutASkybox) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  // A bare model: no skybox, no floor, an unnamed joint. Without the renderer's own sky its
  // background is black.
  const std::string bare = ::testing::TempDir() + "sim_scene_test_bare.xml";
  std::ofstream(bare) << "<mujoco><worldbody><body><joint type=\"hinge\"/>"
                         "<geom type=\"box\" size=\"0.1 0.1 0.1\"/></body></worldbody></mujoco>";
  for (const std::string& file : {kPandaXml, kIiwaXml, model_file("scenes/two_arms.xml"), bare}) {
    SCOPED_TRACE(file);
    const sim::Simulation s = sim::Simulation::from_mjcf_file(file);
    EXPECT_FALSE(s.joint_names().front().empty());
    const PngInfo info = render(s, {});
    ASSERT_EQ(info.width, 320u);
    // The top corners show sky: pale, bluish, not the black MuJoCo clears to.
    for (const int column : {2, 317}) {
      const unsigned char* p = info.at(column, 2);
      EXPECT_GT(brightness(p), 150.0) << "column " << column;
      EXPECT_GE(p[2], p[0]) << "column " << column;
    }
  }
  std::remove(bare.c_str());
  // A URDF imported alone gets the same sky.
  const sim::Simulation urdf = sim::Simulation::from_urdf_file(kUr5eUrdf);
  EXPECT_GT(brightness(render(urdf, {}).at(2, 2)), 150.0);
}

TEST(Rendering, ForceArrowIsDrawnFromItsPointInItsDirection) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_EQ(find_hue(render(s, {}), 'm').count, 0);  // the scene has no magenta of its own

  // Three arrows from one point in front of the flange, in free space, so that the robot hides
  // none of them: magenta along +x, cyan along -x, yellow up.
  sim::RenderOverlay overlay;
  const Eigen::Vector3d from = s.site_pose("flange").position + Eigen::Vector3d(0.25, 0.0, 0.0);
  const auto arrow = [&](const Eigen::Vector3d& force, const Eigen::Vector4f& rgba) {
    return sim::RenderArrow{from, force, 0.01, rgba, ""};  // 15 N: 0.15 m
  };
  overlay.arrows = {arrow({15, 0, 0}, {1, 0, 1, 1}), arrow({-15, 0, 0}, {0, 1, 1, 1}),
                    arrow({0, 0, 15}, {1, 1, 0, 1})};
  const PngInfo info = render(s, overlay);
  const Blob forward = find_hue(info, 'm'), backward = find_hue(info, 'c'),
             up = find_hue(info, 'y');
  // Seen from the robot's right, +x is to the right in the picture and +z up (rows grow down).
  EXPECT_GT(forward.count, 100);
  EXPECT_GT(backward.count, 100);
  EXPECT_GT(up.count, 100);
  EXPECT_GT(forward.column, backward.column + 20);
  EXPECT_LT(up.row, forward.row - 10);
  EXPECT_LT(up.row, backward.row - 10);
  // All three start at one point: the horizontal ones' mean positions straddle it.
  EXPECT_NEAR(up.column, 0.5 * (forward.column + backward.column), 15.0);
}

TEST(Rendering, CaptionIsWrittenInTheTopLeftCorner) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  sim::RenderOverlay overlay;
  overlay.azimuth = 105.0;
  const PngInfo plain = render(s, overlay, 640, 480);
  overlay.caption = "hold - t = 2.00 s\nstiffness 500 N/m\nno external force";
  const PngInfo captioned = render(s, overlay, 640, 480);
  // Text on a dark backdrop in the top-left corner: many pixels differ there, and the caption's
  // white letters are on it.
  const int changed = differing_pixels(plain, captioned, 0, 0, 200, 60);
  EXPECT_GT(changed, 2000);
  int white = 0;
  for (int row = 0; row < 60; ++row) {
    for (int column = 0; column < 200; ++column)
      white += brightness(captioned.at(column, row)) > 220;
  }
  EXPECT_GT(white, 100);
}

// A workspace box is drawn by its edges in its colour (pure blue here: nothing in the Panda's
// scene is), and a box that is not finite is refused naming it.
TEST(Rendering, BoxIsDrawnByItsEdges) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  const auto blue = [](const PngInfo& info) {
    int count = 0;
    for (std::size_t i = 0; i + 2 < info.rgb.size(); i += 3) {
      const int r = info.rgb[i], g = info.rgb[i + 1], b = info.rgb[i + 2];
      count += b > 150 && r < 80 && g < 80;
    }
    return count;
  };
  sim::RenderOverlay overlay;
  overlay.boxes.push_back({Eigen::Vector3d(-0.4, -0.4, 0.0), Eigen::Vector3d(0.6, 0.4, 0.9),
                           Eigen::Vector4f(0.0f, 0.0f, 1.0f, 1.0f), "workspace"});
  EXPECT_LT(blue(render(s, {})), 20);
  EXPECT_GT(blue(render(s, overlay)), 300);
  overlay.boxes[0].max.x() = NAN;
  EXPECT_ERROR([&] { s.render_png("/tmp/x.png", 10, 10, overlay); }, {"boxes[0].max"});
}

TEST(Rendering, GhostAndFrameShowAnotherPose) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  // The camera is fixed by the overlay's direction and the scene's extent: with a ghost turned
  // by 1.2 rad about the first joint the scene grows, so compare against a ghost at the arm's
  // own joint positions (which covers the arm itself and nothing else).
  sim::RenderOverlay overlay;
  overlay.ghost_q = s.q();
  const PngInfo same = render(s, overlay);
  overlay.ghost_q[0] += 1.2;
  const PngInfo turned = render(s, overlay);
  EXPECT_GT(differing_pixels(same, turned, 0, 0, 320, 240), 1500);
  // The ghost is translucent green, a colour the scene has nowhere else.
  const auto greenish = [](const PngInfo& info) {
    int count = 0;
    for (std::size_t i = 0; i + 2 < info.rgb.size(); i += 3) {
      const int r = info.rgb[i], g = info.rgb[i + 1], b = info.rgb[i + 2];
      count += g > r + 30 && g > b + 15;
    }
    return count;
  };
  EXPECT_LT(greenish(render(s, {})), 50);
  EXPECT_GT(greenish(same), 1000);
  EXPECT_ERROR(
      [&] {
        sim::RenderOverlay wrong;
        wrong.ghost_q = JointVector::Zero(3);
        s.render_png("/tmp/x.png", 10, 10, wrong);
      },
      {"ghost_q", "3 entries", "7"});

  sim::RenderOverlay frame;
  sim::RenderFrame reference{s.site_pose("flange"), 0.15, 1.0f, "reference"};
  reference.pose.position.x() += 0.25;  // in free space
  frame.frames.push_back(reference);
  const PngInfo framed = render(s, frame);
  for (const char hue : {'r', 'g', 'b'}) {
    EXPECT_GT(find_hue(framed, hue).count, 20) << "axis colour " << hue;
  }
  EXPECT_EQ(find_hue(render(s, {}), 'r').count, 0);
}
