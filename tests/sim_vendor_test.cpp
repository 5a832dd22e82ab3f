// A robot description package as vendors ship it (tests/vendor/acme_arm_description, written by
// tests/vendor/make_description.py): package:// mesh URIs for visual and collision geometry, STL
// and OBJ meshes, a root link `world`, no <dynamics>, transmissions and gazebo tags. The model
// and both engines load it as it is, and a mesh that cannot be found names what was looked for.

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <sstream>
#include <string>

#include "cartesian_impedance/core/error.hpp"
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

// Relative paths against the URDF's folder, file:// as it is; a missing file and a COLLADA file
// are refused by both engines with the link, the URI and where it was looked for.
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
  const std::string collada =
      error_of([&] { sim::detail::resolve_mesh_file("meshes/tool.dae", urdf, "tool"); });
  EXPECT_NE(collada.find("is a .dae file; the simulation reads STL, OBJ and MSH meshes only"),
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

}  // namespace
