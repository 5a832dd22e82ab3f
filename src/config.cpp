#include "cartesian_impedance/config.hpp"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "cartesian_impedance/error.hpp"

namespace cartesian_impedance {
namespace {

std::string where(std::string_view source, const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  std::string text(source);
  if (mark.line >= 0) text += ":" + std::to_string(mark.line + 1);
  return text + ": ";
}

bool is_prefix_of_parameter(const std::string& path) {
  const std::string prefix = path + ".";
  for (const ParameterInfo& info : parameter_table()) {
    if (info.name.substr(0, prefix.size()) == prefix) return true;
  }
  return false;
}

double read_number(const ParameterInfo& info, const std::string& element, const YAML::Node& node,
                   std::string_view source) {
  double value = 0.0;
  if (!node.IsScalar() || !YAML::convert<double>::decode(node, value)) {
    std::string shown = node.IsScalar() ? "'" + node.Scalar() + "'" : "a list or map";
    throw Error(where(source, node) + element + " = " + shown + " is not a number" +
                (info.unit.empty() || info.unit == "-" ? "" : " [" + std::string(info.unit) + "]"));
  }
  try {
    info.check(element, value);
  } catch (const Error& error) {
    throw Error(where(source, node) + error.what());
  }
  return value;
}

void read_field(const ParameterInfo& info, const YAML::Node& node, Parameters& parameters,
                std::string_view source) {
  const std::string name(info.name);
  const ParameterField field = info.in(parameters);
  if (auto* value = std::get_if<double*>(&field)) {
    **value = read_number(info, name, node, source);
  } else if (auto* vector = std::get_if<Eigen::Vector3d*>(&field)) {
    static constexpr const char* kAxis[3] = {".x", ".y", ".z"};
    if (node.IsScalar()) {
      (*vector)->setConstant(read_number(info, name, node, source));
    } else if (node.IsSequence() && node.size() == 3) {
      for (std::size_t i = 0; i < 3; ++i) {
        (**vector)[static_cast<Eigen::Index>(i)] =
            read_number(info, name + kAxis[i], node[i], source);
      }
    } else {
      throw Error(where(source, node) + name + " must be 3 numbers [x, y, z] or one number" +
                  (node.IsSequence() ? " (got " + std::to_string(node.size()) + ")" : ""));
    }
  } else if (auto* joints = std::get_if<JointVector*>(&field)) {
    if (node.IsScalar()) {
      **joints = JointVector::Constant(1, read_number(info, name, node, source));
    } else if (node.IsSequence() && node.size() >= 1 && node.size() <= kMaxJoints) {
      JointVector values(static_cast<Eigen::Index>(node.size()));
      for (std::size_t i = 0; i < node.size(); ++i) {
        values[static_cast<Eigen::Index>(i)] =
            read_number(info, name + "[" + std::to_string(i) + "]", node[i], source);
      }
      **joints = values;
    } else {
      throw Error(where(source, node) + name + " must be one number or a list of 1 to " +
                  std::to_string(kMaxJoints) + " numbers (one per joint)");
    }
  } else if (auto* flag = std::get_if<bool*>(&field)) {
    bool value = false;
    if (!node.IsScalar() || !YAML::convert<bool>::decode(node, value)) {
      throw Error(where(source, node) + name + " = " +
                  (node.IsScalar() ? "'" + node.Scalar() + "'" : std::string("a list or map")) +
                  " is not true or false");
    }
    **flag = value;
  } else if (auto* frame = std::get_if<Frame*>(&field)) {
    if (!node.IsScalar()) throw Error(where(source, node) + name + " must be base or end_effector");
    try {
      **frame = frame_from_name(name, node.Scalar());
    } catch (const Error& error) {
      throw Error(where(source, node) + error.what());
    }
  }
}

const ParameterInfo* find_row(const std::string& path) {
  for (const ParameterInfo& row : parameter_table()) {
    if (row.name == path) return &row;
  }
  return nullptr;
}

void read_map(const YAML::Node& map, const std::string& prefix, Parameters& parameters,
              std::string_view source) {
  for (const auto& entry : map) {
    const std::string key = entry.first.as<std::string>();
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    const YAML::Node& value = entry.second;
    const bool group = is_prefix_of_parameter(path);
    if (value.IsNull() && group) continue;  // a group with every member commented out
    if (value.IsNull() && find_row(path) != nullptr) {
      throw Error(where(source, entry.first) + path + " has no value");
    }
    if (const ParameterInfo* info = find_row(path)) {
      read_field(*info, value, parameters, source);  // a map here is reported as a shape error
    } else if (value.IsMap() && group) {
      read_map(value, path, parameters, source);
    } else {
      throw Error(where(source, entry.first) + "unknown parameter '" + path + "'" +
                  (group ? " (it is a group; give its members)" : ""));
    }
  }
}

}  // namespace

Parameters parameters_from_yaml(const std::string& yaml, std::string_view source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception& error) {
    throw Error(std::string(source) + ": malformed YAML: " + error.what());
  }
  Parameters parameters;
  if (root.IsNull()) return parameters;
  if (!root.IsMap()) throw Error(where(source, root) + "the top level must be a map of parameters");
  read_map(root, "", parameters, source);
  try {
    validate(parameters);
  } catch (const Error& error) {
    throw Error(std::string(source) + ": " + error.what());
  }
  return parameters;
}

Parameters load_parameters(const std::string& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) {
    throw Error("parameter file '" + path + "' is a directory");
  }
  std::ifstream file(path);
  if (!file) throw Error("cannot open parameter file '" + path + "'");
  std::stringstream text;
  text << file.rdbuf();
  return parameters_from_yaml(text.str(), path);
}

void save_parameters(const std::string& path, const Parameters& parameters) {
  std::ofstream file(path);
  file << parameters_to_yaml(parameters);
  file.close();
  if (!file) throw Error("cannot write parameter file '" + path + "'");
}

std::string parameters_to_yaml(const Parameters& parameters) {
  // The table lists the members of each group together, so one pass with a stack of open groups
  // writes the nested maps in table order.
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  std::vector<std::string> open;
  for (const ParameterInfo& info : parameter_table()) {
    std::vector<std::string> parts;
    std::string_view name = info.name;
    for (std::size_t dot; (dot = name.find('.')) != std::string_view::npos;) {
      parts.emplace_back(name.substr(0, dot));
      name.remove_prefix(dot + 1);
    }
    std::size_t shared = 0;
    while (shared < open.size() && shared < parts.size() && open[shared] == parts[shared]) ++shared;
    for (; open.size() > shared; open.pop_back()) out << YAML::EndMap;
    for (std::size_t i = shared; i < parts.size(); ++i) {
      out << YAML::Key << parts[i] << YAML::Value << YAML::BeginMap;
      open.push_back(parts[i]);
    }
    out << YAML::Key << std::string(name) << YAML::Value;
    const ParameterField field = info.in(const_cast<Parameters&>(parameters));
    if (auto* value = std::get_if<double*>(&field)) {
      out << **value;
    } else if (auto* vector = std::get_if<Eigen::Vector3d*>(&field)) {
      out << YAML::Flow << YAML::BeginSeq << (**vector)[0] << (**vector)[1] << (**vector)[2]
          << YAML::EndSeq;
    } else if (auto* joints = std::get_if<JointVector*>(&field)) {
      out << YAML::Flow << YAML::BeginSeq;
      for (Eigen::Index i = 0; i < (*joints)->size(); ++i) out << (**joints)[i];
      out << YAML::EndSeq;
    } else if (auto* frame = std::get_if<Frame*>(&field)) {
      out << std::string(frame_name(**frame));
    } else if (auto* flag = std::get_if<bool*>(&field)) {
      out << **flag;
    }
  }
  for (; !open.empty(); open.pop_back()) out << YAML::EndMap;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace cartesian_impedance
