// Several URDF robots in one MuJoCo world. Each is imported as Simulation::from_urdf_file() does
// (detail::mjcf_from_urdf), then its bodies are copied into the first one's document with every
// name prefixed, so that two copies of one arm can stand side by side with distinct joints.

#include <tinyxml2.h>

#include <filesystem>
#include <locale>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cartesian_impedance/sim/simulation.hpp"
#include "simulation_impl.hpp"

namespace cartesian_impedance::sim {
namespace {

namespace fs = std::filesystem;

// Attributes that name an object of the robot, or refer to one. Asset references (mesh,
// material) are renamed too, since two different URDFs may both name a mesh "link1".
const char* const kNames[] = {"name", "body1", "body2", "joint", "site", "mesh", "material"};

void prefix_names(tinyxml2::XMLElement* element, const std::string& prefix) {
  for (const char* attribute : kNames) {
    const char* value = element->Attribute(attribute);
    if (value != nullptr) element->SetAttribute(attribute, (prefix + value).c_str());
  }
  for (tinyxml2::XMLElement* e = element->FirstChildElement(); e != nullptr;
       e = e->NextSiblingElement()) {
    prefix_names(e, prefix);
  }
}

std::string format_position(const Eigen::Vector3d& p) {
  std::ostringstream text;
  text.imbue(std::locale::classic());
  text.precision(17);
  text << p.x() << ' ' << p.y() << ' ' << p.z();
  return text.str();
}

Eigen::Vector3d read_position(const tinyxml2::XMLElement* body) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  if (const char* pos = body->Attribute("pos")) {
    std::istringstream text(pos);
    text.imbue(std::locale::classic());
    text >> p.x() >> p.y() >> p.z();
  }
  return p;
}

tinyxml2::XMLElement* section(tinyxml2::XMLDocument& document, const char* name) {
  tinyxml2::XMLElement* root = document.FirstChildElement("mujoco");
  tinyxml2::XMLElement* element = root->FirstChildElement(name);
  if (element == nullptr) element = root->InsertEndChild(document.NewElement(name))->ToElement();
  return element;
}

// The directory the imported document's relative mesh files are relative to.
fs::path mesh_directory(tinyxml2::XMLDocument& document, const std::string& urdf) {
  const fs::path base = fs::absolute(urdf).parent_path();
  const tinyxml2::XMLElement* compiler =
      document.FirstChildElement("mujoco")->FirstChildElement("compiler");
  const char* meshdir = compiler != nullptr ? compiler->Attribute("meshdir") : nullptr;
  return meshdir == nullptr ? base : base / meshdir;
}

}  // namespace

Simulation make_robots_scene(const std::vector<SceneRobot>& robots, SimulationOptions options) {
  if (robots.empty()) throw Error("make_robots_scene: no robots given");
  std::set<std::string> prefixes;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    const std::string field = "robots[" + std::to_string(i) + "]";
    if (!robots[i].base_position.allFinite()) {
      throw Error(field + ".base_position = (" + format_position(robots[i].base_position) +
                  ") m is not finite");
    }
    if (!prefixes.insert(robots[i].prefix).second) {
      throw Error(field + ".prefix = '" + robots[i].prefix +
                  "' is used by another robot; each robot needs its own, or their names clash");
    }
    for (char c : robots[i].prefix) {
      if (c == '"' || c == '<' || c == '>' || c == '&') {
        throw Error(field + ".prefix = '" + robots[i].prefix +
                    "' contains a character that cannot appear in an XML attribute (\" < > &)");
      }
    }
  }

  // The first robot's document keeps its floor, lights and sky and receives every robot.
  tinyxml2::XMLDocument scene;
  detail::UrdfImportOptions import;
  import.boxes_for_missing_meshes = options.boxes_for_missing_meshes;
  scene.Parse(detail::mjcf_from_urdf(robots[0].urdf, import).c_str());
  detail::UrdfScene urdf_scene{robots, {}, {}};
  import.warnings = &urdf_scene.warnings;
  tinyxml2::XMLElement* world = section(scene, "worldbody");
  tinyxml2::XMLElement* assets = section(scene, "asset");
  std::vector<tinyxml2::XMLElement*> own;  // the first robot's bodies and meshes, moved below
  for (tinyxml2::XMLElement* e = world->FirstChildElement("body"); e != nullptr;
       e = e->NextSiblingElement("body")) {
    own.push_back(e);
  }
  for (tinyxml2::XMLElement* e = assets->FirstChildElement("mesh"); e != nullptr;
       e = e->NextSiblingElement("mesh")) {
    own.push_back(e);
  }
  // Pairs of bodies that MuJoCo's import excludes from contact come back prefixed below.
  if (tinyxml2::XMLElement* contact =
          scene.FirstChildElement("mujoco")->FirstChildElement("contact")) {
    own.push_back(contact);
  }
  for (tinyxml2::XMLElement* e : own) e->Parent()->DeleteChild(e);
  if (tinyxml2::XMLElement* compiler =
          scene.FirstChildElement("mujoco")->FirstChildElement("compiler")) {
    compiler->DeleteAttribute("meshdir");  // every mesh file below is absolute
  }

  std::vector<std::string> attached_names;
  for (std::size_t r = 0; r < robots.size(); ++r) {
    const SceneRobot& robot = robots[r];
    tinyxml2::XMLDocument imported;
    imported.Parse(detail::attach_boxes(detail::mjcf_from_urdf(robot.urdf, import), robot.attached,
                                        "robots[" + std::to_string(r) + "].attached", robot.urdf)
                       .c_str());
    for (std::size_t i = 0; i < robot.attached.size(); ++i) {
      attached_names.push_back(robot.prefix + detail::attached_name(robot.attached[i], i));
    }
    const fs::path meshes = mesh_directory(imported, robot.urdf);
    tinyxml2::XMLElement* asset = section(imported, "asset");
    for (tinyxml2::XMLElement* mesh = asset->FirstChildElement("mesh"); mesh != nullptr;
         mesh = mesh->NextSiblingElement("mesh")) {
      tinyxml2::XMLElement* copy = mesh->DeepClone(&scene)->ToElement();
      prefix_names(copy, robot.prefix);
      if (const char* file = mesh->Attribute("file")) {
        copy->SetAttribute("file", (meshes / file).lexically_normal().string().c_str());
      }
      assets->InsertEndChild(copy);
    }
    for (tinyxml2::XMLElement* body = section(imported, "worldbody")->FirstChildElement("body");
         body != nullptr; body = body->NextSiblingElement("body")) {
      tinyxml2::XMLElement* copy = body->DeepClone(&scene)->ToElement();
      prefix_names(copy, robot.prefix);
      copy->SetAttribute("pos", format_position(read_position(body) + robot.base_position).c_str());
      world->InsertEndChild(copy);
    }
    if (tinyxml2::XMLElement* contact =
            imported.FirstChildElement("mujoco")->FirstChildElement("contact")) {
      tinyxml2::XMLElement* copy = contact->DeepClone(&scene)->ToElement();
      prefix_names(copy, robot.prefix);
      scene.FirstChildElement("mujoco")->InsertEndChild(copy);
    }
  }

  tinyxml2::XMLPrinter printer;
  scene.Print(&printer);
  const fs::path first = fs::absolute(robots[0].urdf);
  const std::string name = first.stem().string() + "_cartesian_impedance_robots.xml";
  const detail::VirtualFile file(name, printer.CStr());
  return detail::load_simulation((first.parent_path() / name).string(), file.vfs(),
                                 "scene of " + std::to_string(robots.size()) + " robots",
                                 std::move(options), &urdf_scene, attached_names);
}

}  // namespace cartesian_impedance::sim
