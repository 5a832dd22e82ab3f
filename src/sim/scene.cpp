#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <locale>
#include <memory>
#include <optional>
#include <sstream>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "simulation_impl.hpp"

namespace cartesian_impedance::sim {
namespace {

struct VfsDeleter {
  void operator()(mjVFS* vfs) const noexcept {
    mj_deleteVFS(vfs);
    delete vfs;
  }
};

// Name of the document's root element: skips the XML declaration, comments and a DOCTYPE.
std::string root_element(const std::string& document) {
  std::size_t at = 0;
  while (true) {
    at = document.find('<', at);
    if (at == std::string::npos) return "";
    if (document.compare(at, 4, "<!--") == 0) {
      at = document.find("-->", at);
      if (at == std::string::npos) return "";
    } else if (document.compare(at, 2, "<?") == 0 || document.compare(at, 2, "<!") == 0) {
      at = document.find('>', at);
      if (at == std::string::npos) return "";
    } else {
      const std::size_t end = document.find_first_of(" \t\r\n/>", at + 1);
      return document.substr(at + 1, end == std::string::npos ? end : end - at - 1);
    }
  }
}

}  // namespace

Box Box::table(const Eigen::Vector2d& center_xy, const Eigen::Vector2d& half_size_xy, double top_z,
               const std::string& name) {
  Box box;
  box.name = name;
  box.center = Eigen::Vector3d(center_xy.x(), center_xy.y(), 0.5 * top_z);
  box.half_size = Eigen::Vector3d(half_size_xy.x(), half_size_xy.y(), 0.5 * top_z);
  return box;
}

Simulation make_scene(const std::string& robot_mjcf, const std::vector<Box>& boxes,
                      SimulationOptions options) {
  return make_scene(robot_mjcf, boxes, {}, std::move(options));
}

Simulation make_scene(const std::string& robot_mjcf, const std::vector<Box>& boxes,
                      const std::vector<AttachedBox>& attached, SimulationOptions options) {
  constexpr double kSoftestBox = 0.05;  // [s] Box::time_constant
  detail::check_attached(attached, "attached");
  std::ostringstream geoms;
  geoms.imbue(std::locale::classic());
  geoms.precision(17);
  geoms << "\n  <!-- added by cartesian_impedance::sim::make_scene -->\n  <worldbody>\n";
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const Box& box = boxes[i];
    const std::string field = "boxes[" + std::to_string(i) + "]";
    checks::finite_vector(field + ".center", box.center);
    checks::finite_vector(field + ".half_size", box.half_size);
    checks::finite_vector(field + ".orientation", box.orientation.coeffs());
    for (int k = 0; k < 3; ++k) {
      if (!(box.half_size[k] > 0.0)) {
        const std::string input = field + ".half_size";
        const Fault fault{input.c_str(), k, box.half_size[k], "is not > 0", 0.0, false, "m"};
        throw Error(fault, to_string(fault));
      }
    }
    if (!(box.time_constant >= 0.0 && box.time_constant <= kSoftestBox)) {
      throw Error(field + ".time_constant = " + format_number(box.time_constant) +
                  " s is outside [0, " + format_number(kSoftestBox) +
                  "] s: a softer MuJoCo contact lets a body sink through the box (the Panda's "
                  "flange under 20 N did at 0.07 s)");
    }
    if (box.orientation.norm() < 1e-9) {
      throw Error(field + ".orientation has zero norm; expected a unit quaternion");
    }
    for (char c : box.name) {
      if (c == '"' || c == '<' || c == '>' || c == '&') {
        throw Error(field + ".name = '" + box.name +
                    "' contains a character that cannot appear in an XML attribute (\" < > &)");
      }
    }
    const Eigen::Quaterniond q = box.orientation.normalized();
    const std::string name = box.name.empty() ? "scene_box_" + std::to_string(i) : box.name;
    // contype/conaffinity 1 explicitly: the robot's default class may give geoms contype 0
    // (the project's robots do, so that the arm does not collide with itself).
    geoms << "    <geom name=\"" << name << "\" type=\"box\" pos=\"" << box.center.x() << ' '
          << box.center.y() << ' ' << box.center.z() << "\" size=\"" << box.half_size.x() << ' '
          << box.half_size.y() << ' ' << box.half_size.z() << "\" quat=\"" << q.w() << ' ' << q.x()
          << ' ' << q.y() << ' ' << q.z()
          << "\" contype=\"1\" conaffinity=\"1\" rgba=\"0.62 0.48 0.34 1\"";
    // A higher priority than the robot's geoms: the contact takes the box's solref alone.
    if (box.time_constant > 0.0) {
      geoms << " priority=\"1\" solref=\"" << box.time_constant << " 1\"";
    }
    geoms << "/>\n";
  }
  geoms << "  </worldbody>\n";

  std::error_code error_code;
  if (!std::filesystem::is_regular_file(robot_mjcf, error_code)) {
    throw Error("MJCF file '" + robot_mjcf + "' does not exist or is not a regular file");
  }
  std::ifstream file(robot_mjcf, std::ios::binary);
  std::stringstream content;
  content << file.rdbuf();
  if (!file) throw Error("cannot read MJCF file '" + robot_mjcf + "'");
  std::string document = content.str();

  // A second <worldbody> section is merged with the first by MuJoCo's parser, so the boxes can
  // go right before the closing tag without parsing the robot file.
  // A URDF becomes the same complete model Simulation::from_urdf_file() simulates.
  std::optional<detail::UrdfScene> urdf_scene;
  if (root_element(document) == "robot") {
    urdf_scene = detail::UrdfScene{
        {SceneRobot{robot_mjcf, "", Eigen::Vector3d::Zero(), attached}}, boxes, {}};
    detail::UrdfImportOptions import;
    import.boxes_for_missing_meshes = options.boxes_for_missing_meshes;
    import.warnings = &urdf_scene->warnings;
    document = detail::mjcf_from_urdf(robot_mjcf, import);
  }
  std::vector<std::string> attached_names;
  for (std::size_t i = 0; i < attached.size(); ++i) {
    attached_names.push_back(detail::attached_name(attached[i], i));
  }
  const std::string root = root_element(document);
  const std::size_t end = document.rfind("</mujoco>");
  if (root != "mujoco" || end == std::string::npos) {
    throw Error("make_scene: '" + robot_mjcf + "' is not an MJCF file (root element <" + root +
                "> instead of <mujoco>); expected an MJCF robot file");
  }
  document.insert(end, geoms.str());
  document = detail::attach_boxes(document, attached, "attached", robot_mjcf);

  // The combined document goes into MuJoCo's virtual file system under a name in the robot
  // file's directory: the loader finds it there first, and resolves the robot's relative
  // include/mesh/texture paths against that directory as for the original file.
  const std::filesystem::path robot_path = std::filesystem::absolute(robot_mjcf);
  const std::string scene_name =
      robot_path.stem().string() + "_cartesian_impedance_scene" + robot_path.extension().string();
  const std::string scene_path = (robot_path.parent_path() / scene_name).string();

  std::unique_ptr<mjVFS, VfsDeleter> vfs(new mjVFS);  // about 2 MB: not on the stack
  mj_defaultVFS(vfs.get());
  const int size = static_cast<int>(document.size());
  if (mj_makeEmptyFileVFS(vfs.get(), scene_name.c_str(), size) != 0) {
    throw Error("cannot create '" + scene_name + "' in MuJoCo's virtual file system");
  }
  const int index = mj_findFileVFS(vfs.get(), scene_name.c_str());
  std::copy(document.begin(), document.end(), static_cast<char*>(vfs->filedata[index]));
  return detail::load_simulation(scene_path, vfs.get(), "scene (" + robot_mjcf + " with boxes)",
                                 std::move(options), urdf_scene ? &*urdf_scene : nullptr,
                                 attached_names);
}

}  // namespace cartesian_impedance::sim
