#include "cartesian_impedance/config.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <locale>
#include <sstream>
#include <unordered_map>
#include <vector>

#include "cartesian_impedance/error.hpp"

namespace cartesian_impedance {
namespace {

std::string where(std::string_view source, const YAML::Mark& mark) {
  std::string text(source);
  if (mark.line >= 0) text += ":" + std::to_string(mark.line + 1);
  return text + ": ";
}

std::string where(std::string_view source, const YAML::Node& node) {
  return where(source, node.Mark());
}

// How a value that is not what was expected is shown in a message.
std::string describe(const YAML::Node& node) {
  if (node.IsScalar()) return "'" + node.Scalar() + "'";
  if (node.IsSequence()) return "a list";
  if (node.IsMap()) return "a map";
  return "empty";
}

// "!!str" for yaml-cpp's "tag:yaml.org,2002:str".
std::string tag_text(const std::string& tag) {
  const std::string standard = "tag:yaml.org,2002:";
  return tag.compare(0, standard.size(), standard) == 0 ? "!!" + tag.substr(standard.size()) : tag;
}

// yaml-cpp converts the text of any scalar, but in YAML a quoted scalar (or a block scalar, both
// tagged "!") is a string, and a tag says what a scalar is: only a plain, untagged scalar ("?")
// may be read as a number or a switch.
void require_plain(const std::string& element, const YAML::Node& node, std::string_view source,
                   const char* expected) {
  if (!node.IsScalar() || node.Tag() == "?") return;
  if (node.Tag() == "!") {
    throw Error(where(source, node) + element + " = " + describe(node) +
                " is quoted (or a block scalar), which makes it a string in YAML; expected " +
                expected + " without quotes");
  }
  throw Error(where(source, node) + element + " = " + describe(node) + " has the tag " +
              tag_text(node.Tag()) + "; expected " + expected + " without a tag");
}

// True if `text` is a decimal number too large for a double, e.g. 1e400, which yaml-cpp does not
// convert: such a value is out of range, not a typo, and is reported with the range.
bool overflows(const std::string& text) {
  std::istringstream stream(text);
  stream.imbue(std::locale::classic());
  double value = 0.0;
  stream >> value;
  // On overflow the stream fails and holds the largest double ([facet.num.get.virtuals]); eof
  // means the number was the whole text.
  return stream.fail() && stream.eof() && std::abs(value) == std::numeric_limits<double>::max();
}

// How many levels deep the parameter table nests its keys ("limits.stiffness.translation.min": 4).
std::size_t table_depth() {
  std::size_t depth = 0;
  for (const ParameterInfo& info : parameter_table()) {
    depth = std::max(
        depth, 1 + static_cast<std::size_t>(std::count(info.name.begin(), info.name.end(), '.')));
  }
  return depth;
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
  require_plain(element, node, source, "a number");
  double value = 0.0;
  if (!node.IsScalar() || !YAML::convert<double>::decode(node, value)) {
    if (node.IsScalar() && overflows(node.Scalar())) {
      throw Error(where(source, node) + element + " = " + node.Scalar() +
                  " overflows a double (valid: " + info.range_text() + ")");
    }
    throw Error(where(source, node) + element + " = " + describe(node) + " is not a number" +
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
    require_plain(name, node, source, "true or false");
    bool value = false;
    if (!node.IsScalar() || !YAML::convert<bool>::decode(node, value)) {
      throw Error(where(source, node) + name + " = " + describe(node) + " is not true or false");
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

// Reads the map of group `prefix` ("" for the top level). It descends only into maps whose path
// begins a parameter name, so its recursion ends at the depth of the parameter table whatever the
// nesting of the YAML (and an alias of a map inside itself ends at the first unknown key).
void read_map(const YAML::Node& map, const std::string& prefix, Parameters& parameters,
              std::string_view source) {
  const std::string in = prefix.empty() ? "" : "in " + prefix + ": ";
  // yaml-cpp keeps every entry of a map, so a key given twice would silently take the value read
  // last; and a key that is not a name (a list, a map, empty) has no path at all.
  std::unordered_map<std::string, int> lines;
  for (const auto& entry : map) {
    const YAML::Node& key = entry.first;
    if (!key.IsScalar()) {
      // An empty key has no position of its own in yaml-cpp; its value or map has.
      YAML::Mark mark = key.Mark();
      if (mark.line < 0) mark = entry.second.Mark();
      if (mark.line < 0) mark = map.Mark();
      throw Error(where(source, mark) + in + "a key is " + describe(key) +
                  "; expected a parameter name");
    }
    const auto [first, inserted] = lines.emplace(key.Scalar(), key.Mark().line + 1);
    if (!inserted) {
      const std::string path = prefix.empty() ? key.Scalar() : prefix + "." + key.Scalar();
      throw Error(where(source, key) + "'" + path + "' is given twice, on lines " +
                  std::to_string(first->second) + " and " + std::to_string(key.Mark().line + 1) +
                  "; expected each key once");
    }
  }
  for (const auto& entry : map) {
    const std::string key = entry.first.Scalar();
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
                  (group ? " (it is a group; give its members)" : "") +
                  (key == "<<" ? " (merge keys are not supported; write the values out)" : ""));
    }
  }
}

}  // namespace

Parameters parameters_from_yaml(const std::string& yaml, std::string_view source) {
  // Every document, not only the first (YAML::Load ignores the rest), so that a second one is
  // reported rather than silently dropped.
  std::vector<YAML::Node> documents;
  try {
    documents = YAML::LoadAll(yaml);
  } catch (const YAML::DeepRecursion& error) {
    // yaml-cpp's parser recurses once per level and stops at a bound of its own.
    throw Error(where(source, error.mark) + "the YAML is nested too deeply (" +
                std::to_string(error.depth()) + " levels); parameters are nested at most " +
                std::to_string(table_depth()) + " levels deep");
  } catch (const YAML::Exception& error) {
    std::string column;
    if (!error.mark.is_null()) column = " (column " + std::to_string(error.mark.column + 1) + ")";
    throw Error(where(source, error.mark) + "malformed YAML: " + error.msg + column);
  }
  if (documents.size() > 1) {
    // An empty document has the position of the end of the text, which would mislead.
    const YAML::Mark mark = documents[1].IsNull() ? YAML::Mark::null_mark() : documents[1].Mark();
    throw Error(where(source, mark) +
                "a second YAML document (after '---'); a parameter file holds only one document");
  }
  Parameters parameters;
  if (documents.empty() || documents[0].IsNull()) return parameters;
  const YAML::Node& root = documents[0];
  if (!root.IsMap()) throw Error(where(source, root) + "the top level must be a map of parameters");
  try {
    read_map(root, "", parameters, source);
  } catch (const YAML::Exception& error) {
    // Reading only asks for what it checked is there; should yaml-cpp still object, it is an
    // Error like any other.
    throw Error(where(source, error.mark) + "cannot read the YAML: " + error.msg);
  }
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
