// Geometry fixed to a robot body (AttachedBox) in the MJCF scene, and the peg-in-hole scene built
// from it. DART builds the same bodies from the same AttachedBox values (dart_physics.cpp).

#include <tinyxml2.h>

#include <cmath>
#include <locale>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/sim/peg_in_hole.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "simulation_impl.hpp"

namespace cartesian_impedance::sim {
namespace detail {
namespace {

std::string numbers(std::initializer_list<double> values) {
  std::ostringstream text;
  text.imbue(std::locale::classic());
  text.precision(17);
  const char* separator = "";
  for (const double value : values) {
    text << separator << value;
    separator = " ";
  }
  return text.str();
}

[[noreturn]] void not_above_zero(const std::string& field, int index, double value,
                                 const char* unit) {
  const Fault fault{field.c_str(), index, value, "is not > 0", 0.0, false, unit};
  throw Error(fault, to_string(fault));
}

void check_xml_name(const std::string& field, const std::string& name) {
  for (const char c : name) {
    if (c == '"' || c == '<' || c == '>' || c == '&') {
      throw Error(field + " = '" + name +
                  "' contains a character that cannot appear in an XML attribute (\" < > &)");
    }
  }
}

tinyxml2::XMLElement* find_body(tinyxml2::XMLElement* parent, const std::string& name) {
  for (tinyxml2::XMLElement* body = parent->FirstChildElement("body"); body != nullptr;
       body = body->NextSiblingElement("body")) {
    const char* body_name = body->Attribute("name");
    if (body_name != nullptr && name == body_name) return body;
    if (tinyxml2::XMLElement* found = find_body(body, name)) return found;
  }
  return nullptr;
}

void list_bodies(const tinyxml2::XMLElement* parent, std::string& names) {
  for (const tinyxml2::XMLElement* body = parent->FirstChildElement("body"); body != nullptr;
       body = body->NextSiblingElement("body")) {
    if (const char* name = body->Attribute("name"))
      names += (names.empty() ? "" : ", ") + std::string(name);
    list_bodies(body, names);
  }
}

}  // namespace

std::string attached_name(const AttachedBox& box, std::size_t index) {
  return box.name.empty() ? "attached_box_" + std::to_string(index) : box.name;
}

void check_attached(const std::vector<AttachedBox>& attached, const std::string& field) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < attached.size(); ++i) {
    const AttachedBox& box = attached[i];
    const std::string at = field + "[" + std::to_string(i) + "]";
    checks::finite_vector(at + ".position", box.position, "m");
    checks::unit_quaternion(at + ".orientation", box.orientation);
    checks::finite_vector(at + ".half_size", box.half_size, "m");
    for (int k = 0; k < 3; ++k) {
      if (!(box.half_size[k] > 0.0)) not_above_zero(at + ".half_size", k, box.half_size[k], "m");
    }
    checks::finite(at + ".mass", box.mass, "kg");
    if (!(box.mass > 0.0)) not_above_zero(at + ".mass", -1, box.mass, "kg");
    check_xml_name(at + ".name", box.name);
    check_xml_name(at + ".body", box.body);
    if (!names.insert(attached_name(box, i)).second) {
      throw Error(at + ".name = '" + attached_name(box, i) +
                  "' is used by another attached box; each needs its own");
    }
  }
}

std::string attach_boxes(const std::string& document, const std::vector<AttachedBox>& attached,
                         const std::string& field, const std::string& source) {
  check_attached(attached, field);
  if (attached.empty()) return document;
  tinyxml2::XMLDocument mjcf;
  if (mjcf.Parse(document.c_str()) != tinyxml2::XML_SUCCESS) {
    throw Error("cannot attach boxes to '" + source +
                "': it is not well-formed XML: " + mjcf.ErrorStr());
  }
  tinyxml2::XMLElement* root = mjcf.FirstChildElement("mujoco");
  tinyxml2::XMLElement* world = root != nullptr ? root->FirstChildElement("worldbody") : nullptr;
  for (std::size_t i = 0; i < attached.size(); ++i) {
    const AttachedBox& box = attached[i];
    tinyxml2::XMLElement* parent = world != nullptr ? find_body(world, box.body) : nullptr;
    if (parent == nullptr) {
      std::string bodies;
      if (world != nullptr) list_bodies(world, bodies);
      throw Error(field + "[" + std::to_string(i) + "].body = '" + box.body +
                  "' is not a body of '" + source +
                  "'; its bodies are: " + (bodies.empty() ? "(none)" : bodies));
    }
    const std::string name = attached_name(box, i);
    const Eigen::Vector3d& p = box.position;
    const Eigen::Quaterniond q = box.orientation.normalized();
    const Eigen::Vector3d s = box.half_size;
    // A body of its own (welded: no joint), so that its inertia is explicit whatever the file's
    // compiler says about inertia from geoms, and so that the gravity compensation can leave it
    // out by name.
    tinyxml2::XMLElement* body = mjcf.NewElement("body");
    body->SetAttribute("name", name.c_str());
    body->SetAttribute("pos", numbers({p.x(), p.y(), p.z()}).c_str());
    body->SetAttribute("quat", numbers({q.w(), q.x(), q.y(), q.z()}).c_str());
    tinyxml2::XMLElement* inertial = mjcf.NewElement("inertial");
    inertial->SetAttribute("pos", "0 0 0");
    inertial->SetAttribute("mass", numbers({box.mass}).c_str());
    const double third = box.mass / 3.0;
    inertial->SetAttribute("diaginertia", numbers({third * (s.y() * s.y() + s.z() * s.z()),
                                                   third * (s.x() * s.x() + s.z() * s.z()),
                                                   third * (s.x() * s.x() + s.y() * s.y())})
                                              .c_str());
    body->InsertEndChild(inertial);
    // Like the robot's own geoms: contype 0, conaffinity 1 collides with the scene's boxes
    // (contype 1) and not with the robot.
    tinyxml2::XMLElement* geom = mjcf.NewElement("geom");
    geom->SetAttribute("name", name.c_str());
    geom->SetAttribute("type", "box");
    geom->SetAttribute("size", numbers({s.x(), s.y(), s.z()}).c_str());
    // The same mass on the geom: a file whose compiler takes inertia from geoms
    // (inertiafromgeom="true") then computes the same body.
    geom->SetAttribute("mass", numbers({box.mass}).c_str());
    geom->SetAttribute("contype", 0);
    geom->SetAttribute("conaffinity", 1);
    geom->SetAttribute("rgba", "0.85 0.6 0.15 1");
    body->InsertEndChild(geom);
    parent->InsertEndChild(body);
  }
  tinyxml2::XMLPrinter printer;
  mjcf.Print(&printer);
  return printer.CStr();
}

}  // namespace detail

std::vector<Box> hole_boxes(const SquareHole& hole) {
  checks::finite_vector("hole.opening.position", hole.opening.position, "m");
  const Eigen::Quaterniond orientation =
      checks::unit_quaternion("hole.opening.orientation", hole.opening.orientation);
  const auto positive = [](const char* field, double value) {
    checks::finite(field, value, "m");
    if (!(value > 0.0)) detail::not_above_zero(field, -1, value, "m");
  };
  const auto not_negative = [](const char* field, double value) {
    checks::finite(field, value, "m");
    if (value < 0.0) {
      const Fault fault{field, -1, value, "is not >= 0", 0.0, false, "m"};
      throw Error(fault, to_string(fault));
    }
  };
  positive("hole.peg_half_width", hole.peg_half_width);
  not_negative("hole.clearance", hole.clearance);
  positive("hole.depth", hole.depth);
  positive("hole.wall", hole.wall);
  not_negative("hole.floor", hole.floor);
  detail::check_xml_name("hole.name", hole.name);

  const double half_opening = hole.peg_half_width + 0.5 * hole.clearance;
  const double half_block = half_opening + hole.wall;
  const double half_depth = 0.5 * hole.depth;
  // In the hole's frame: the opening at z = 0, the hole going down to -depth.
  struct Local {
    const char* suffix;
    Eigen::Vector3d center, half_size;
  };
  std::vector<Local> parts = {
      {"_wall_x_plus",
       {half_opening + 0.5 * hole.wall, 0, -half_depth},
       {0.5 * hole.wall, half_block, half_depth}},
      {"_wall_x_minus",
       {-half_opening - 0.5 * hole.wall, 0, -half_depth},
       {0.5 * hole.wall, half_block, half_depth}},
      {"_wall_y_plus",
       {0, half_opening + 0.5 * hole.wall, -half_depth},
       {half_opening, 0.5 * hole.wall, half_depth}},
      {"_wall_y_minus",
       {0, -half_opening - 0.5 * hole.wall, -half_depth},
       {half_opening, 0.5 * hole.wall, half_depth}},
  };
  if (hole.floor > 0.0) {
    parts.push_back({"_floor",
                     {0, 0, -hole.depth - 0.5 * hole.floor},
                     {half_block, half_block, 0.5 * hole.floor}});
  }
  std::vector<Box> boxes;
  for (const Local& part : parts) {
    Box box;
    box.name = hole.name + part.suffix;
    box.center = hole.opening.position + orientation * part.center;
    box.half_size = part.half_size;
    box.orientation = orientation;
    boxes.push_back(box);
  }
  return boxes;
}

Simulation make_peg_in_hole_scene(const PegInHole& scene, SimulationOptions options) {
  checks::finite("peg_length", scene.peg_length, "m");
  if (!(scene.peg_length > 0.0)) detail::not_above_zero("peg_length", -1, scene.peg_length, "m");
  checks::finite("peg_mass", scene.peg_mass, "kg");
  if (!(scene.peg_mass > 0.0)) detail::not_above_zero("peg_mass", -1, scene.peg_mass, "kg");
  const std::vector<Box> boxes = hole_boxes(scene.hole);
  AttachedBox peg;
  peg.name = scene.peg_name;
  peg.body = scene.flange;
  peg.position = Eigen::Vector3d(0, 0, 0.5 * scene.peg_length);
  peg.half_size =
      Eigen::Vector3d(scene.hole.peg_half_width, scene.hole.peg_half_width, 0.5 * scene.peg_length);
  peg.mass = scene.peg_mass;
  return make_scene(scene.robot, boxes, {peg}, std::move(options));
}

// Here, beside the geometry a scene attaches to a flange: simulation.cpp is at the 800-line cap.
bool Simulation::has_collision_geometry(const std::string& body) const {
  const mjModel* m = impl_->model.get();
  const int weld = m->body_weldid[impl_->find_body(body)];
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->body_weldid[m->geom_bodyid[g]] == weld && (m->geom_contype[g] | m->geom_conaffinity[g]))
      return true;
  }
  return false;
}

}  // namespace cartesian_impedance::sim
