// A robot description package as vendors ship it (tests/vendor/acme_arm_description, written by
// tests/vendor/make_description.py): package:// mesh URIs for visual and collision geometry, STL
// and OBJ meshes, a root link `world`, no <dynamics>, transmissions and gazebo tags. The model
// and both engines load it as it is, and a mesh that cannot be found names what was looked for.

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <stdlib.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <sstream>
#include <string>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/link_inertia.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "src/sim/simulation_impl.hpp"
#include "support/errors.hpp"

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
namespace fs = std::filesystem;

namespace {

using test_errors::error_of;

const std::string kVendor = std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/tests/vendor";
const std::string kPackage = kVendor + "/acme_arm_description";
const std::string kUrdf = kPackage + "/urdf/acme6.urdf";

std::string read(const std::string& path) {
  std::ifstream file(path);
  std::stringstream content;
  content << file.rdbuf();
  return content.str();
}

// A folder of the test's own (ctest runs the cases of this binary in parallel processes).
fs::path scratch(const std::string& name) {
  const fs::path folder =
      fs::path(::testing::TempDir()) / ("sim_vendor_test_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(folder);
  fs::create_directories(folder);
  return folder;
}

// Sets an environment variable for one test and restores it after.
class ScopedEnvironment {
 public:
  ScopedEnvironment(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old, had_ = true;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnvironment() {
    if (had_) {
      ::setenv(name_, old_.c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }
  ScopedEnvironment(const ScopedEnvironment&) = delete;
  ScopedEnvironment& operator=(const ScopedEnvironment&) = delete;

 private:
  const char* name_;
  std::string old_;
  bool had_ = false;
};

class VendorPackage : public ::testing::TestWithParam<sim::Engine> {};

// Before: MuJoCo's import looked for base_link_0.stl in urdf/ (strippath, no package://) and the
// simulation did not load at all.
TEST_P(VendorPackage, LoadsAsShippedWithItsCollisionMeshes) {
  std::string reason;
  if (!sim::engine_available(GetParam(), &reason)) GTEST_SKIP() << reason;
  // Outside a ROS workspace: the package is found as the folder above the URDF.
  ScopedEnvironment no_ros("ROS_PACKAGE_PATH", "");
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(kUrdf, "base_link", "tool0");
  sim::SimulationOptions options;
  options.engine = GetParam();
  sim::Simulation simulation = sim::Simulation::from_urdf_file(kUrdf, options);
  ASSERT_EQ(simulation.num_joints(), model.num_joints());
  EXPECT_EQ(simulation.num_joints(), 6);
  // One mesh per <collision> (14: 7 STL, 7 OBJ); the visual OBJs are not simulated.
  const std::string mjcf = sim::detail::mjcf_from_urdf(kUrdf, {});
  int meshes = 0;
  for (std::size_t at = mjcf.find("<mesh "); at != std::string::npos;
       at = mjcf.find("<mesh ", at + 1)) {
    ++meshes;
  }
  EXPECT_EQ(meshes, 14);
  EXPECT_EQ(mjcf.find("/meshes/visual/"), std::string::npos);
  // The flange keeps its collision geometry (the contact checks press on it).
  EXPECT_NE(mjcf.find("tool0_0"), std::string::npos);
  // Gravity holds still from rest: the meshes changed no mass (they carry none in a URDF).
  simulation.step();
  EXPECT_TRUE(simulation.q().allFinite());
}

// The demo's contact checks ask this before pressing the flange on a table: a flange whose
// meshes were stripped reads 0 N, which is n/a (nothing can press), not a FAIL.
TEST(VendorMeshes, FlangeCollisionGeometryIsReported) {
  ScopedEnvironment no_ros("ROS_PACKAGE_PATH", "");
  const sim::Simulation simulation = sim::Simulation::from_urdf_file(kUrdf);
  EXPECT_TRUE(simulation.has_collision_geometry("tool0"));
  EXPECT_TRUE(simulation.has_collision_geometry("link_6"));
  // tool0 is welded to link_6: without link_6's and tool0's <collision> nothing is left.
  std::string text = read(kUrdf);
  for (const char* link : {"<link name=\"link_6\">", "<link name=\"tool0\">"}) {
    const std::size_t begin = text.find(link), end = text.find("</link>", begin);
    text = text.substr(0, begin) +
           std::regex_replace(text.substr(begin, end - begin),
                              std::regex("<collision>[\\s\\S]*?</collision>"), "") +
           text.substr(end);
  }
  const fs::path folder = scratch("stripped");
  const fs::path copy = folder / "acme6.urdf";
  std::ofstream(copy) << text;
  ScopedEnvironment ros("ROS_PACKAGE_PATH", kVendor);
  const sim::Simulation stripped = sim::Simulation::from_urdf_file(copy.string());
  EXPECT_FALSE(stripped.has_collision_geometry("tool0"));
  EXPECT_TRUE(stripped.has_collision_geometry("link_5"));
  EXPECT_THROW(stripped.has_collision_geometry("no_such_link"), ci::Error);
  fs::remove_all(folder);
}

INSTANTIATE_TEST_SUITE_P(BothEngines, VendorPackage,
                         ::testing::Values(sim::Engine::mujoco, sim::Engine::dart),
                         [](const auto& info) {
                           return info.param == sim::Engine::mujoco ? std::string("mujoco")
                                                                    : std::string("dart");
                         });

// package:// through ROS_PACKAGE_PATH when the URDF is elsewhere (as a workspace's install space
// or a copied URDF has it); without it, the error lists every place looked.
TEST(VendorMeshes, PackageUrisResolveThroughRosPackagePath) {
  const fs::path folder = scratch("copy");
  const std::string copy = (folder / "acme6.urdf").string();
  std::ofstream(copy) << read(kUrdf);
  {
    ScopedEnvironment ros("ROS_PACKAGE_PATH", "/nonexistent:" + kVendor);
    EXPECT_EQ(sim::detail::resolve_mesh_file(
                  "package://acme_arm_description/meshes/collision/link_2_0.obj", copy, "link_2"),
              kPackage + "/meshes/collision/link_2_0.obj");
    EXPECT_NO_THROW(sim::Simulation::from_urdf_file(copy));
  }
  ScopedEnvironment no_ros("ROS_PACKAGE_PATH", "/nonexistent");
  const std::string message = error_of([&] { sim::Simulation::from_urdf_file(copy); });
  EXPECT_NE(message.find("link 'base_link': mesh "
                         "'package://acme_arm_description/meshes/collision/base_link_0.stl' not "
                         "found; looked in:"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("/nonexistent/acme_arm_description/meshes/collision/base_link_0.stl "
                         "(ROS_PACKAGE_PATH)"),
            std::string::npos)
      << message;
  EXPECT_NE(
      message.find((folder / "acme_arm_description/meshes/collision/base_link_0.stl").string() +
                   " (the URDF's folders)"),
      std::string::npos)
      << message;
  EXPECT_NE(message.find("14 collision mesh(es) cannot be used"), std::string::npos) << message;
  fs::remove_all(folder);
}

// Relative paths against the URDF's folder, file:// as it is; a missing file and a broken COLLADA
// file are refused by both engines with the link, the URI and where it was looked for.
TEST(VendorMeshes, RelativeFileAndUnreadableMeshes) {
  const fs::path folder = scratch("relative");
  fs::create_directories(folder / "meshes");
  fs::copy_file(kPackage + "/meshes/collision/link_1_0.stl", folder / "meshes" / "tool.stl");
  std::ofstream(folder / "meshes" / "tool.dae") << "<COLLADA/>";
  const std::string urdf = (folder / "arm.urdf").string();
  EXPECT_EQ(sim::detail::resolve_mesh_file("meshes/tool.stl", urdf, "tool"),
            (folder / "meshes" / "tool.stl").string());
  EXPECT_EQ(sim::detail::resolve_mesh_file("file://" + (folder / "meshes" / "tool.stl").string(),
                                           urdf, "tool"),
            (folder / "meshes" / "tool.stl").string());
  const std::string missing =
      error_of([&] { sim::detail::resolve_mesh_file("meshes/gone.stl", urdf, "tool"); });
  EXPECT_EQ(missing, "link 'tool': mesh 'meshes/gone.stl' not found; looked in:\n  " +
                         (folder / "meshes" / "gone.stl").string() + " (the URDF's folder)");
  // A file assimp cannot read is named with its path (the converter's words follow).
  const std::string collada =
      error_of([&] { sim::detail::resolve_mesh_file("meshes/tool.dae", urdf, "tool"); });
  EXPECT_NE(collada.find("link 'tool': mesh 'meshes/tool.dae' found at '" +
                         (folder / "meshes" / "tool.dae").string() + "' cannot be read by assimp"),
            std::string::npos)
      << collada;
  EXPECT_NE(error_of([&] {
              sim::detail::resolve_mesh_file("http://x/y.stl", urdf, "tool");
            }).find("only package://, file:// and plain paths"),
            std::string::npos);

  // Both engines refuse the URDF with a missing collision mesh before loading anything.
  std::string text = read(kUrdf);
  text = std::regex_replace(text, std::regex("collision/tool0_0\\.obj"), "collision/tool0_9.stl");
  const std::string broken = (folder / "broken.urdf").string();
  std::ofstream(broken) << text;
  ScopedEnvironment ros("ROS_PACKAGE_PATH", kVendor);
  for (const sim::Engine engine : {sim::Engine::mujoco, sim::Engine::dart}) {
    if (!sim::engine_available(engine)) continue;
    sim::SimulationOptions options;
    options.engine = engine;
    const std::string message = error_of([&] { sim::Simulation::from_urdf_file(broken, options); });
    EXPECT_NE(message.find("1 collision mesh(es) cannot be used"), std::string::npos) << message;
    EXPECT_NE(message.find("link 'tool0': mesh "
                           "'package://acme_arm_description/meshes/collision/tool0_9.stl'"),
              std::string::npos)
        << message;
  }
  fs::remove_all(folder);
}

// The package with link_2's <inertia> line replaced (the shipped one: ixx 0.00530397, iyy and
// izz 0.01732135547), in a folder of its own beside which the package is found.
std::string with_link_2_inertia(const fs::path& folder, const std::string& inertia) {
  fs::copy(kPackage, folder / "acme_arm_description", fs::copy_options::recursive);
  const std::string urdf = (folder / "acme_arm_description/urdf/acme6.urdf").string();
  const std::string text = read(urdf);
  const std::size_t link = text.find("<link name=\"link_2\">");
  const std::size_t begin = text.find("<inertia ", link), end = text.find("/>", begin) + 2;
  std::ofstream(urdf) << text.substr(0, begin) + inertia + text.substr(end);
  return urdf;
}

// One notion of a valid arm (link_inertia.hpp). Before: the model loaded principal moments
// that break A + B >= C without a word and both engines refused them (MuJoCo: "use
// 'balanceinertia' to fix"). Now all three use the same repaired tensor, and the model says so.
TEST(VendorInertia, TriangleInequalityIsRepairedAlikeByTheModelAndBothEngines) {
  const fs::path folder = scratch("triangle");
  // A + B = 0.0106079 < C = 0.0173214: a violation of 6.7e-3 kg m^2, 24 % of the sum.
  const double a = 0.00530397, c = 0.01732135547;
  const std::string urdf = with_link_2_inertia(
      folder,
      "<inertia ixx=\"0.00530397\" ixy=\"0\" ixz=\"0\" iyy=\"0.00530397\" iyz=\"0\" "
      "izz=\"0.01732135547\"/>");
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(urdf, "base_link", "tool0");
  ASSERT_EQ(model.warnings().size(), 1u);
  const std::string& warning = model.warnings()[0];
  EXPECT_NE(warning.find("link 'link_2': principal moments (0.00530397, 0.00530397, 0.0173214) "
                         "kg m^2 break the triangle inequality"),
            std::string::npos)
      << warning;
  // The projection along (1, 1, -1) onto A + B = C keeps the sum: each moves by the excess / 3.
  // A and B up, C down twice as much (the sum stays), to 1e-9 of the sum inside the limit.
  const double shift = (c - 2.0 * a + 1e-9 * (2.0 * a + c)) / 4.0;
  const double a_repaired = a + shift, c_repaired = c - 2.0 * shift;
  // The model is the one of a file written with the repaired moments (its mass matrix agrees to
  // rounding).
  char repaired[200];
  std::snprintf(
      repaired, sizeof(repaired),
      "<inertia ixx=\"%.17g\" ixy=\"0\" ixz=\"0\" iyy=\"%.17g\" iyz=\"0\" izz=\"%.17g\"/>",
      a_repaired, a_repaired, c_repaired);
  const fs::path by_hand_folder = scratch("triangle_by_hand");
  const ci::RobotModel by_hand = ci::RobotModel::from_urdf_file(
      with_link_2_inertia(by_hand_folder, repaired), "base_link", "tool0");
  EXPECT_TRUE(by_hand.warnings().empty());
  ci::ModelWorkspace w1(model), w2(by_hand);
  ci::Kinematics k1 = w1.make_kinematics(), k2 = w2.make_kinematics();
  ci::JointVector q(6);
  q << 0.3, -0.7, 1.1, 0.4, -0.9, 0.2;
  ASSERT_TRUE(w1.compute(q, ci::JointVector::Zero(6), k1, ci::ModelTerms::all));
  ASSERT_TRUE(w2.compute(q, ci::JointVector::Zero(6), k2, ci::ModelTerms::all));
  EXPECT_LT((k1.mass - k2.mass).cwiseAbs().maxCoeff(), 1e-10);
  // MuJoCo compiles the same moments (its MJCF states them per body); DART loads the same text.
  const std::string mjcf = sim::detail::mjcf_from_urdf(urdf, {});
  const std::size_t body = mjcf.find("<body name=\"link_2\"");
  const std::size_t diag = mjcf.find("diaginertia=\"", body) + 13;
  std::istringstream moments(mjcf.substr(diag, mjcf.find('"', diag) - diag));
  Eigen::Vector3d compiled;
  moments >> compiled[0] >> compiled[1] >> compiled[2];
  std::sort(compiled.data(), compiled.data() + 3);
  EXPECT_LT((compiled - Eigen::Vector3d(a_repaired, a_repaired, c_repaired)).cwiseAbs().maxCoeff(),
            1e-14 * c)
      << compiled.transpose();
  for (const sim::Engine engine : {sim::Engine::mujoco, sim::Engine::dart}) {
    if (!sim::engine_available(engine)) continue;
    sim::SimulationOptions options;
    options.engine = engine;
    EXPECT_NO_THROW(sim::Simulation::from_urdf_file(urdf, options));
  }
  fs::remove_all(folder);
  fs::remove_all(by_hand_folder);
}

// What no repair can tell the meaning of is refused by all three, with the same words.
TEST(VendorInertia, ImpossibleInertiasAreRefusedAlikeNamingTheLinkAndTheValue) {
  struct Case {
    std::string inertia, expected;
  };
  const Case cases[] = {
      {"<inertia ixx=\"0.01\" ixy=\"0.02\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/>",
       "link 'link_2' has an inertia tensor that is not positive semi-definite (principal moments "
       "(-0.01, 0.01, 0.03) kg m^2"},
      {"<inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"2e6\" iyz=\"0\" izz=\"0.01\"/>",
       "link 'link_2' has inertia iyy = 2e+06 kg m^2; expected finite entries within +-1e+06"},
  };
  int index = 0;
  for (const Case& c : cases) {
    const fs::path folder = scratch("refused_" + std::to_string(index++));
    const std::string urdf = with_link_2_inertia(folder, c.inertia);
    const std::string from_model =
        error_of([&] { ci::RobotModel::from_urdf_file(urdf, "base_link", "tool0"); });
    EXPECT_NE(from_model.find(c.expected), std::string::npos) << from_model;
    for (const sim::Engine engine : {sim::Engine::mujoco, sim::Engine::dart}) {
      if (!sim::engine_available(engine)) continue;
      sim::SimulationOptions options;
      options.engine = engine;
      const std::string from_engine =
          error_of([&] { sim::Simulation::from_urdf_file(urdf, options); });
      EXPECT_NE(from_engine.find(c.expected), std::string::npos) << from_engine;
      EXPECT_NE(from_engine.find(urdf), std::string::npos) << from_engine;
    }
    fs::remove_all(folder);
  }
  // A negative mass: the same for all three.
  EXPECT_NE(error_of([] {
              ci::physical_link_inertia("l", -1.0, Eigen::Matrix3d::Identity());
            }).find("link 'l' has mass = -1 kg; expected a finite value >= 0 kg"),
            std::string::npos);
  // A flat plate lies on the limit (A, B, A + B) and a box inside it: used exactly as written. A
  // violation by rounding (1e-12 of the sum) is moved inside without a warning.
  const Eigen::Matrix3d plate = Eigen::Vector3d(0.02, 0.1, 0.12).asDiagonal();
  const ci::LinkInertia plate_used = ci::physical_link_inertia("plate", 1.0, plate);
  EXPECT_TRUE(plate_used.repair.empty());
  EXPECT_EQ(plate_used.inertia, plate);
  const Eigen::Matrix3d box = Eigen::Vector3d(0.05, 0.1, 0.12).asDiagonal();
  EXPECT_EQ(ci::physical_link_inertia("box", 1.0, box).inertia, box);
  const Eigen::Matrix3d rounded = Eigen::Vector3d(0.02, 0.1, 0.12 + 1e-11).asDiagonal();
  const ci::LinkInertia rounded_used = ci::physical_link_inertia("rounded", 1.0, rounded);
  EXPECT_TRUE(rounded_used.repair.empty());
  EXPECT_LE(rounded_used.inertia(2, 2), rounded_used.inertia(0, 0) + rounded_used.inertia(1, 1));
  EXPECT_LE((rounded_used.inertia - rounded).cwiseAbs().maxCoeff(), 1e-9 * 0.24);
}

// The corners of the box around a binary STL's vertices.
std::pair<Eigen::Vector3d, Eigen::Vector3d> stl_bounds(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  char header[80];
  std::uint32_t count = 0;
  file.read(header, sizeof(header));
  file.read(reinterpret_cast<char*>(&count), sizeof(count));
  Eigen::Vector3d low = Eigen::Vector3d::Constant(1e300), high = -low;
  for (std::uint32_t t = 0; t < count && file; ++t) {
    float values[12];
    std::uint16_t attribute = 0;
    file.read(reinterpret_cast<char*>(values), sizeof(values));
    file.read(reinterpret_cast<char*>(&attribute), sizeof(attribute));
    for (int corner = 1; corner < 4; ++corner) {
      const Eigen::Vector3d v(values[3 * corner], values[3 * corner + 1], values[3 * corner + 2]);
      low = low.cwiseMin(v);
      high = high.cwiseMax(v);
    }
  }
  EXPECT_TRUE(file) << path;
  return {low, high};
}

// COLLADA, as description packages ship it: converted with assimp to the same geometry as the
// STL written beside it, in metres whether the file counts in metres (gamma_robot) or in
// millimetres (beta_description, <unit meter="0.001">). Before: refused ("reads STL, OBJ and
// MSH meshes only").
TEST(VendorMeshes, ColladaMeshesAreConvertedWithTheirUnit) {
  const std::string gamma = kVendor + "/gamma_robot";
  const std::string beta = kVendor + "/beta_description";
  const struct {
    std::string urdf, dae, stl;
  } pairs[] = {
      {gamma + "/urdf/gamma6.urdf", "../meshes/collision/link_2_0.dae",
       gamma + "/meshes/link_2.STL"},
      {beta + "/urdf/beta7.urdf", "package://beta_description/meshes/visual/link_2_0.dae",
       beta + "/meshes/collision/link_2_0.stl"},
  };
  ScopedEnvironment no_ros("ROS_PACKAGE_PATH", "");
  for (const auto& pair : pairs) {
    const std::string converted = sim::detail::resolve_mesh_file(pair.dae, pair.urdf, "link_2");
    EXPECT_EQ(fs::path(converted).extension(), ".stl");
    const auto [low, high] = stl_bounds(converted);
    const auto [expected_low, expected_high] = stl_bounds(pair.stl);
    // The DAE has 6 decimals of its unit (1e-9 m in millimetres), the STLs single precision.
    EXPECT_LT((low - expected_low).cwiseAbs().maxCoeff(), 2e-6) << pair.dae;
    EXPECT_LT((high - expected_high).cwiseAbs().maxCoeff(), 2e-6) << pair.dae;
    EXPECT_GT((high - low).maxCoeff(), 0.05);  // a link, not a point
    // A second load takes the cached copy.
    EXPECT_EQ(sim::detail::resolve_mesh_file(pair.dae, pair.urdf, "link_2"), converted);
  }
}

// A package whose meshes are not (yet) in place: refused, naming the way out; with
// boxes_for_missing_meshes, each such link is simulated as the uniform box of its inertia by
// both engines, and the simulation says which.
TEST(VendorMeshes, MissingMeshesBecomeTheBoxOfTheLinksInertia) {
  const fs::path folder = scratch("boxes");
  fs::copy(kPackage, folder / "acme_arm_description", fs::copy_options::recursive);
  const fs::path meshes = folder / "acme_arm_description/meshes/collision";
  fs::remove(meshes / "link_2_0.obj");
  fs::remove(meshes / "link_2_1.stl");
  const std::string urdf = (folder / "acme_arm_description/urdf/acme6.urdf").string();
  ScopedEnvironment no_ros("ROS_PACKAGE_PATH", "");
  const std::string refused = error_of([&] { sim::Simulation::from_urdf_file(urdf); });
  EXPECT_NE(refused.find("2 collision mesh(es) cannot be used"), std::string::npos) << refused;
  EXPECT_NE(refused.find("--boxes-for-missing-meshes"), std::string::npos) << refused;
  // link_2: 2.875920688 kg, moments (0.00530397, 0.01732135547, 0.01732135547) kg m^2; the box
  // with them has sides sqrt(6 (B + C - A) / m): 0.2474 m along the tube, 0.1052 m across.
  const double m = 2.875920688, a = 0.00530397, b = 0.01732135547;
  char sides[64];
  std::snprintf(sides, sizeof(sides), "a box of %.4g %.4g %.4g m", std::sqrt(6 * (2 * b - a) / m),
                std::sqrt(6 * a / m), std::sqrt(6 * a / m));
  for (const sim::Engine engine : {sim::Engine::mujoco, sim::Engine::dart}) {
    if (!sim::engine_available(engine)) continue;
    sim::SimulationOptions options;
    options.engine = engine;
    options.boxes_for_missing_meshes = true;
    const sim::Simulation simulation = sim::Simulation::from_urdf_file(urdf, options);
    ASSERT_EQ(simulation.warnings().size(), 1u);
    const std::string& warning = simulation.warnings()[0];
    EXPECT_NE(warning.find("link 'link_2': mesh "
                           "'package://acme_arm_description/meshes/collision/link_2_0.obj' not "
                           "found"),
              std::string::npos)
        << warning;
    EXPECT_NE(warning.find(sides), std::string::npos) << warning << "\n" << sides;
    EXPECT_TRUE(simulation.has_collision_geometry("link_2"));
  }
  fs::remove_all(folder);
}

// MuJoCo 2.2 writes its MJCF with 6 significant digits (2.875920688 kg became 2.87592 kg); the
// import writes each body's placement and inertial again to the last digit, so that MuJoCo
// simulates the URDF's numbers.
TEST(VendorMeshes, MujocoSimulatesTheUrdfsNumbersToTheLastDigit) {
  ScopedEnvironment no_ros("ROS_PACKAGE_PATH", "");
  const std::string mjcf = sim::detail::mjcf_from_urdf(kUrdf, {});
  const std::size_t body = mjcf.find("<body name=\"link_2\"");
  ASSERT_NE(body, std::string::npos);
  const std::size_t at = mjcf.find("mass=\"", mjcf.find("<inertial", body)) + 6;
  EXPECT_EQ(std::stod(mjcf.substr(at, mjcf.find('"', at) - at)), 2.875920688);
}

}  // namespace
