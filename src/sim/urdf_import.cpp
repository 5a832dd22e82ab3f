// One path from a URDF to a simulated robot.
// MuJoCo 2.2's URDF import merges fixed links into their parents, keeps no armature, and gives
// no floor, light or sky. So the URDF is imported with fusestatic="false", saved back as MJCF
// (mj_saveLastXML), and that MJCF is completed: rotor inertia (armature) and damping on every
// joint that has none, arm geoms that do not collide with each other, a floor, lights and a sky.

#include <mujoco/mujoco.h>
#include <stdlib.h>
#include <tinyxml2.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cartesian_impedance/model/link_inertia.hpp"
#include "simulation_impl.hpp"

namespace cartesian_impedance::sim::detail {
namespace {

std::string read_file(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  std::stringstream content;
  content << file.rdbuf();
  if (!file) throw Error("cannot read '" + path + "'");
  return content.str();
}

tinyxml2::XMLElement* child(tinyxml2::XMLDocument& document, tinyxml2::XMLElement* parent,
                            const char* name, bool first = false) {
  tinyxml2::XMLElement* element = parent->FirstChildElement(name);
  if (element != nullptr) return element;
  element = document.NewElement(name);
  if (first) {
    parent->InsertFirstChild(element);
  } else {
    parent->InsertEndChild(element);
  }
  return element;
}

std::string print(tinyxml2::XMLDocument& document) {
  tinyxml2::XMLPrinter printer;
  document.Print(&printer);
  return printer.CStr();
}

/// An empty file of a unique name in the temporary folder, removed when this goes (also when
/// the conversion throws).
struct TemporaryPath {
  explicit TemporaryPath(const std::string& urdf_path) {
    std::error_code ignored;
    path =
        (std::filesystem::temp_directory_path(ignored) / "cartesian_impedance_XXXXXX.xml").string();
    const int fd = ::mkstemps(path.data(), 4);
    if (fd < 0) {
      throw Error("cannot convert URDF file '" + urdf_path +
                  "' to MJCF: cannot create a temporary file '" + path +
                  "': " + std::strerror(errno));
    }
    ::close(fd);
  }
  TemporaryPath(const TemporaryPath&) = delete;
  TemporaryPath& operator=(const TemporaryPath&) = delete;
  ~TemporaryPath() {
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
  }
  std::string path;
};

std::vector<std::string> split_path_list(const char* variable) {
  std::vector<std::string> entries;
  const char* value = std::getenv(variable);
  if (value == nullptr) return entries;
  std::stringstream stream(value);
  std::string entry;
  while (std::getline(stream, entry, ':')) {
    if (!entry.empty()) entries.push_back(entry);
  }
  return entries;
}

std::string lowercase_extension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

// The places a package://NAME/rest URI may be, in the order ROS tools try them: the package
// path variables first, then the folders around the URDF (a description package checked out
// without a ROS workspace has its URDF in NAME/urdf/).
std::vector<std::pair<std::filesystem::path, std::string>> package_candidates(
    const std::string& package, const std::string& rest, const std::filesystem::path& urdf_folder) {
  namespace fs = std::filesystem;
  std::vector<std::pair<fs::path, std::string>> candidates;
  for (const std::string& entry : split_path_list("ROS_PACKAGE_PATH")) {
    candidates.emplace_back(fs::path(entry) / package / rest, "ROS_PACKAGE_PATH");
    if (fs::path(entry).lexically_normal().filename() == package) {
      candidates.emplace_back(fs::path(entry) / rest, "ROS_PACKAGE_PATH");
    }
  }
  for (const std::string& entry : split_path_list("AMENT_PREFIX_PATH")) {
    candidates.emplace_back(fs::path(entry) / "share" / package / rest, "AMENT_PREFIX_PATH");
  }
  for (fs::path folder = urdf_folder;; folder = folder.parent_path()) {
    if (folder.filename() == package) candidates.emplace_back(folder / rest, "the URDF's folders");
    candidates.emplace_back(folder / package / rest, "the URDF's folders");
    if (folder == folder.parent_path()) break;
  }
  return candidates;
}

constexpr const char* kInertiaEntries[6] = {"ixx", "ixy", "ixz", "iyy", "iyz", "izz"};

// A link's <inertial> as written: its <inertia> element (to write back), mass and tensor. Null
// when the element or one of its numbers is missing: an engine's parser refuses that anyway (and
// the model's stricter one names it).
struct WrittenInertial {
  tinyxml2::XMLElement* inertia = nullptr;
  double mass = 0.0;
  Eigen::Matrix3d tensor = Eigen::Matrix3d::Zero();
};
WrittenInertial written_inertial(tinyxml2::XMLElement* link) {
  WrittenInertial result;
  tinyxml2::XMLElement* inertial = link->FirstChildElement("inertial");
  tinyxml2::XMLElement* mass = inertial ? inertial->FirstChildElement("mass") : nullptr;
  tinyxml2::XMLElement* inertia = inertial ? inertial->FirstChildElement("inertia") : nullptr;
  double i[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  if (mass == nullptr || inertia == nullptr ||
      mass->QueryDoubleAttribute("value", &result.mass) != tinyxml2::XML_SUCCESS) {
    return {};
  }
  for (int k = 0; k < 6; ++k) {
    if (inertia->QueryDoubleAttribute(kInertiaEntries[k], &i[k]) != tinyxml2::XML_SUCCESS) {
      return {};
    }
  }
  result.inertia = inertia;
  result.tensor << i[0], i[1], i[2], i[1], i[3], i[4], i[2], i[4], i[5];
  return result;
}

std::string link_name(const tinyxml2::XMLElement* link) {
  const char* name = link->Attribute("name");
  return name != nullptr ? name : "";
}

// The uniform box of `link`'s mass and principal moments as a <collision> of the link (placed
// at its centre of mass, turned to its principal axes); "" if the link has no mass. Its sides:
// a^2 = 6 (B + C - A) / m and so on.
std::string inertia_box(tinyxml2::XMLElement* link) {
  const WrittenInertial written = written_inertial(link);
  if (written.inertia == nullptr || !(written.mass > 0.0)) return "";
  tinyxml2::XMLElement* inertial = link->FirstChildElement("inertial");
  const LinkInertia checked = physical_link_inertia(link_name(link), written.mass, written.tensor);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(checked.inertia);
  const Eigen::Vector3d moment = solver.eigenvalues();
  Eigen::Matrix3d axes = solver.eigenvectors();
  if (axes.determinant() < 0.0) axes.col(2) = -axes.col(2);
  Eigen::Vector3d side;
  for (int k = 0; k < 3; ++k) {
    const double sum = moment.sum() - 2.0 * moment[k];  // B + C - A
    side[k] = std::sqrt(std::max(6.0 * sum / written.mass, 0.0));
  }
  side = side.cwiseMax(1e-3);  // a rod's zero thickness as 1 mm
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero(), rpy = Eigen::Vector3d::Zero();
  if (tinyxml2::XMLElement* origin = inertial->FirstChildElement("origin")) {
    std::istringstream(origin->Attribute("xyz") ? origin->Attribute("xyz") : "0 0 0") >> xyz[0] >>
        xyz[1] >> xyz[2];
    std::istringstream(origin->Attribute("rpy") ? origin->Attribute("rpy") : "0 0 0") >> rpy[0] >>
        rpy[1] >> rpy[2];
  }
  const Eigen::Matrix3d turned = (Eigen::AngleAxisd(rpy[2], Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(rpy[1], Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(rpy[0], Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix() *
                                 axes;
  const Eigen::Vector3d ypr = turned.eulerAngles(2, 1, 0);  // URDF rpy: R = Rz(y) Ry(p) Rx(r)
  char text[3][96];
  std::snprintf(text[0], sizeof(text[0]), "%.9g %.9g %.9g", xyz[0], xyz[1], xyz[2]);
  std::snprintf(text[1], sizeof(text[1]), "%.9g %.9g %.9g", ypr[2], ypr[1], ypr[0]);
  std::snprintf(text[2], sizeof(text[2]), "%.4g %.4g %.4g", side[0], side[1], side[2]);
  tinyxml2::XMLDocument& document = *link->GetDocument();
  tinyxml2::XMLElement* collision = document.NewElement("collision");
  tinyxml2::XMLElement* origin = document.NewElement("origin");
  origin->SetAttribute("xyz", text[0]);
  origin->SetAttribute("rpy", text[1]);
  collision->InsertEndChild(origin);
  tinyxml2::XMLElement* geometry = document.NewElement("geometry");
  tinyxml2::XMLElement* box = document.NewElement("box");
  box->SetAttribute("size", text[2]);
  geometry->InsertEndChild(box);
  collision->InsertEndChild(geometry);
  link->InsertEndChild(collision);
  return std::string("a box of ") + text[2] + " m from its inertia";
}

// MuJoCo 2.2 writes its MJCF with 6 significant digits (a mass of 4.970684 kg as 4.97068 kg, a
// quaternion 0.7071068 as 0.707107): a body's placement and inertial are written again from the
// model compiled from the URDF, to the last digit, so that the simulation is the URDF's arm and
// the controller's model, and moments that lie on the triangle limit stay on it.
void write_full_precision(tinyxml2::XMLElement* body, const mjModel* m) {
  const char* name = body->Attribute("name");
  const int id = name != nullptr ? mj_name2id(m, mjOBJ_BODY, name) : -1;
  if (id < 0) return;
  const auto numbers = [](const mjtNum* values, int count) {
    std::string text;
    char number[32];
    for (int k = 0; k < count; ++k) {
      std::snprintf(number, sizeof(number), "%.17g", values[k]);
      text += (k > 0 ? " " : "") + std::string(number);
    }
    return text;
  };
  body->SetAttribute("pos", numbers(m->body_pos + 3 * id, 3).c_str());
  body->SetAttribute("quat", numbers(m->body_quat + 4 * id, 4).c_str());
  if (tinyxml2::XMLElement* inertial = body->FirstChildElement("inertial")) {
    inertial->SetAttribute("pos", numbers(m->body_ipos + 3 * id, 3).c_str());
    inertial->SetAttribute("quat", numbers(m->body_iquat + 4 * id, 4).c_str());
    inertial->SetAttribute("mass", numbers(m->body_mass + id, 1).c_str());
    inertial->SetAttribute("diaginertia", numbers(m->body_inertia + 3 * id, 3).c_str());
  }
}

}  // namespace

std::string resolve_mesh_file(const std::string& uri, const std::string& urdf_path,
                              const std::string& link) {
  namespace fs = std::filesystem;
  const fs::path urdf_folder = fs::absolute(urdf_path).lexically_normal().parent_path();
  const std::string what = "link '" + link + "': mesh '" + uri + "'";
  std::vector<std::pair<fs::path, std::string>> candidates;
  const std::string package_scheme = "package://", file_scheme = "file://";
  if (uri.rfind(package_scheme, 0) == 0) {
    const std::string rest = uri.substr(package_scheme.size());
    const std::size_t slash = rest.find('/');
    if (slash == std::string::npos || slash == 0 || slash + 1 == rest.size()) {
      throw Error(what + " is not of the form package://NAME/PATH");
    }
    candidates = package_candidates(rest.substr(0, slash), rest.substr(slash + 1), urdf_folder);
  } else {
    const fs::path path = uri.rfind(file_scheme, 0) == 0 ? uri.substr(file_scheme.size()) : uri;
    if (uri.find("://") != std::string::npos && uri.rfind(file_scheme, 0) != 0) {
      throw Error(what + ": only package://, file:// and plain paths are supported");
    }
    candidates.emplace_back(path.is_absolute() ? path : urdf_folder / path,
                            path.is_absolute() ? "absolute path" : "the URDF's folder");
  }
  std::string looked;
  for (const auto& [candidate, source] : candidates) {
    const fs::path normal = candidate.lexically_normal();
    std::error_code ignored;
    if (fs::is_regular_file(normal, ignored)) {
      if (!std::ifstream(normal, std::ios::binary)) {
        throw Error(what + " found at '" + normal.string() + "' cannot be read");
      }
      const std::string extension = lowercase_extension(normal);
      if (extension == ".stl" || extension == ".obj" || extension == ".msh") return normal.string();
      // MuJoCo 2.2 reads no other format; assimp (as rviz and Gazebo) reads COLLADA and more.
      return converted_mesh(normal.string(), what);
    }
    looked += "\n  " + normal.string() + " (" + source + ")";
  }
  throw Error(what + " not found; looked in:" + looked);
}

void resolve_collision_meshes(tinyxml2::XMLElement* robot, const std::string& urdf_path,
                              const UrdfImportOptions& options) {
  std::string problems;
  int count = 0;
  for (tinyxml2::XMLElement* link = robot->FirstChildElement("link"); link != nullptr;
       link = link->NextSiblingElement("link")) {
    while (tinyxml2::XMLElement* visual = link->FirstChildElement("visual")) {
      link->DeleteChild(visual);
    }
    const std::string name = link_name(link);
    std::vector<tinyxml2::XMLElement*> missing;
    std::string why;
    for (tinyxml2::XMLElement* collision = link->FirstChildElement("collision");
         collision != nullptr; collision = collision->NextSiblingElement("collision")) {
      tinyxml2::XMLElement* geometry = collision->FirstChildElement("geometry");
      tinyxml2::XMLElement* mesh =
          geometry != nullptr ? geometry->FirstChildElement("mesh") : nullptr;
      if (mesh == nullptr) continue;
      const char* filename = mesh->Attribute("filename");
      try {
        if (filename == nullptr) {
          throw Error("link '" + name + "': <collision> <mesh> has no filename");
        }
        mesh->SetAttribute("filename", resolve_mesh_file(filename, urdf_path, name).c_str());
      } catch (const Error& error) {
        problems += std::string("\n") + error.what();
        why += std::string(why.empty() ? "" : "; ") + error.what();
        missing.push_back(collision);
        ++count;
      }
    }
    if (!options.boxes_for_missing_meshes || missing.empty()) continue;
    for (tinyxml2::XMLElement* collision : missing) link->DeleteChild(collision);
    std::string replacement = inertia_box(link);
    if (options.warnings != nullptr) {
      options.warnings->push_back(why + "; " +
                                  (replacement.empty()
                                       ? "the link has no mass, so it is simulated without "
                                         "collision geometry"
                                       : "simulated as " + replacement));
    }
  }
  if (count > 0 && !options.boxes_for_missing_meshes) {
    throw Error("URDF file '" + urdf_path + "': " + std::to_string(count) +
                " collision mesh(es) cannot be used (visual meshes are not simulated; "
                "SimulationOptions::boxes_for_missing_meshes, the demo's --boxes-for-missing-"
                "meshes, puts the box of each link's inertia in their place):" +
                problems);
  }
}

void apply_physical_inertias(tinyxml2::XMLElement* robot, const std::string& urdf_path) {
  for (tinyxml2::XMLElement* link = robot->FirstChildElement("link"); link != nullptr;
       link = link->NextSiblingElement("link")) {
    const WrittenInertial written = written_inertial(link);
    if (written.inertia == nullptr) continue;
    LinkInertia checked;
    try {
      checked = physical_link_inertia(link_name(link), written.mass, written.tensor);
    } catch (const Error& error) {
      throw Error("URDF file '" + urdf_path + "': " + error.what());
    }
    if (checked.inertia == written.tensor) continue;
    const double repaired[6] = {checked.inertia(0, 0), checked.inertia(0, 1),
                                checked.inertia(0, 2), checked.inertia(1, 1),
                                checked.inertia(1, 2), checked.inertia(2, 2)};
    for (int k = 0; k < 6; ++k) written.inertia->SetAttribute(kInertiaEntries[k], repaired[k]);
  }
}

VirtualFile::VirtualFile(const std::string& name, const std::string& content)
    : vfs_(std::make_unique<mjVFS>()) {
  mj_defaultVFS(vfs_.get());
  if (mj_makeEmptyFileVFS(vfs_.get(), name.c_str(), static_cast<int>(content.size())) != 0) {
    mj_deleteVFS(vfs_.get());
    throw Error("cannot create '" + name + "' in MuJoCo's virtual file system");
  }
  std::copy(content.begin(), content.end(),
            static_cast<char*>(vfs_->filedata[mj_findFileVFS(vfs_.get(), name.c_str())]));
}

VirtualFile::~VirtualFile() {
  mj_deleteVFS(vfs_.get());
}

std::string mjcf_from_urdf(const std::string& urdf_path, const UrdfImportOptions& options) {
  tinyxml2::XMLDocument urdf;
  if (urdf.Parse(read_file(urdf_path).c_str()) != tinyxml2::XML_SUCCESS) {
    throw Error("URDF file '" + urdf_path + "' is not well-formed XML: " + urdf.ErrorStr());
  }
  tinyxml2::XMLElement* robot = urdf.FirstChildElement("robot");
  if (robot == nullptr) throw Error("URDF file '" + urdf_path + "' has no <robot> element");
  // Keep every link as a body (a tool frame on a fixed joint stays addressable) and drop the
  // visual meshes, which are not simulated. Collision meshes stay (the contact checks need the
  // flange's geometry) with absolute paths: MuJoCo's URDF import strips the folders by default
  // (strippath) and knows no package:// URIs.
  resolve_collision_meshes(robot, urdf_path, options);
  apply_physical_inertias(robot, urdf_path);
  tinyxml2::XMLElement* compiler = child(urdf, child(urdf, robot, "mujoco", true), "compiler");
  compiler->SetAttribute("fusestatic", "false");
  compiler->SetAttribute("discardvisual", "true");
  compiler->SetAttribute("strippath", "false");

  // The edited URDF goes through the virtual file system beside the original, so that a
  // <mujoco> section's own relative paths (meshdir) resolve as for the original.
  const std::filesystem::path path = std::filesystem::absolute(urdf_path);
  const std::string name = path.stem().string() + "_cartesian_impedance_import.urdf";
  const std::string text = print(urdf);
  const VirtualFile file(name, text);
  char error[1024] = "";
  ModelPtr model;
  {
    MujocoErrorTrap trap;
    model.reset(mj_loadXML((path.parent_path() / name).c_str(), file.vfs(), error, sizeof(error)));
  }
  if (!model) throw Error("cannot load URDF file '" + urdf_path + "': " + error);

  // MuJoCo 2.2 writes MJCF only to a file. Its name comes from mkstemps (created with O_EXCL):
  // a name made from this process's state (it was the model's address) is the same in every
  // process forked from one parent, as vector environments' workers are, and one of them
  // removed the file another was reading.
  const TemporaryPath saved(urdf_path);
  if (mj_saveLastXML(saved.path.c_str(), model.get(), error, sizeof(error)) == 0) {
    throw Error("cannot convert URDF file '" + urdf_path + "' to MJCF: " + error);
  }
  const std::string saved_text = read_file(saved.path);

  tinyxml2::XMLDocument mjcf;
  if (mjcf.Parse(saved_text.c_str()) != tinyxml2::XML_SUCCESS) {
    throw Error("MuJoCo's MJCF of '" + urdf_path + "' does not parse: " + mjcf.ErrorStr());
  }
  tinyxml2::XMLElement* root = mjcf.FirstChildElement("mujoco");
  tinyxml2::XMLElement* worldbody = child(mjcf, root, "worldbody");

  // Joints: armature and damping where the URDF gave none; arm geoms collide with the
  // environment but not with each other.
  std::vector<tinyxml2::XMLElement*> stack{worldbody};
  while (!stack.empty()) {
    tinyxml2::XMLElement* element = stack.back();
    stack.pop_back();
    for (tinyxml2::XMLElement* e = element->FirstChildElement(); e != nullptr;
         e = e->NextSiblingElement()) {
      const std::string tag = e->Name();
      if (tag == "joint") {
        if (e->Attribute("armature") == nullptr) e->SetAttribute("armature", options.armature);
        if (e->Attribute("damping") == nullptr) e->SetAttribute("damping", options.damping);
      } else if (tag == "geom") {
        e->SetAttribute("contype", 0);
        e->SetAttribute("conaffinity", 1);
      } else if (tag == "body") {
        stack.push_back(e);
        write_full_precision(e, model.get());
      }
    }
  }

  // A floor (drawn, not colliding: the arm stands on it), lights and a sky.
  tinyxml2::XMLElement* asset = child(mjcf, root, "asset");
  asset->InsertEndChild(mjcf.NewElement("texture"));
  tinyxml2::XMLElement* sky = asset->LastChildElement("texture");
  sky->SetAttribute("name", "cartesian_impedance_sky");
  sky->SetAttribute("type", "skybox");
  sky->SetAttribute("builtin", "gradient");
  sky->SetAttribute("rgb1", "0.55 0.7 0.85");
  sky->SetAttribute("rgb2", "0.95 0.97 1");
  sky->SetAttribute("width", 256);
  sky->SetAttribute("height", 256);
  tinyxml2::XMLElement* grid = mjcf.NewElement("texture");
  grid->SetAttribute("name", "cartesian_impedance_grid");
  grid->SetAttribute("type", "2d");
  grid->SetAttribute("builtin", "checker");
  grid->SetAttribute("width", 512);
  grid->SetAttribute("height", 512);
  grid->SetAttribute("rgb1", "0.55 0.6 0.65");
  grid->SetAttribute("rgb2", "0.45 0.5 0.55");
  asset->InsertEndChild(grid);
  tinyxml2::XMLElement* material = mjcf.NewElement("material");
  material->SetAttribute("name", "cartesian_impedance_floor");
  material->SetAttribute("texture", "cartesian_impedance_grid");
  material->SetAttribute("texrepeat", "8 8");
  asset->InsertEndChild(material);

  tinyxml2::XMLElement* floor = mjcf.NewElement("geom");
  floor->SetAttribute("name", "floor");
  floor->SetAttribute("type", "plane");
  floor->SetAttribute("size", "2 2 0.05");
  floor->SetAttribute("material", "cartesian_impedance_floor");
  floor->SetAttribute("contype", 0);
  floor->SetAttribute("conaffinity", 0);
  worldbody->InsertFirstChild(floor);
  for (const char* light_spec : {"0 0 3|0 0 -1|0.8 0.8 0.8", "2 -2 2|-1 1 -1|0.3 0.3 0.3"}) {
    const std::string spec = light_spec;
    const std::size_t a = spec.find('|'), b = spec.find('|', a + 1);
    tinyxml2::XMLElement* light = mjcf.NewElement("light");
    light->SetAttribute("directional", "true");
    light->SetAttribute("pos", spec.substr(0, a).c_str());
    light->SetAttribute("dir", spec.substr(a + 1, b - a - 1).c_str());
    light->SetAttribute("diffuse", spec.substr(b + 1).c_str());
    worldbody->InsertFirstChild(light);
  }
  return print(mjcf);
}

}  // namespace cartesian_impedance::sim::detail
