// Python bindings of Parameters and the parameter table. Every Python value goes to and from the
// library's Parameters through the rows of ci::parameter_table() here: reading a row
// (field_value), writing one (assign_field), dicts of dotted names or nested dicts (flatten,
// parameters_with, read_parameters, parameters_dict) and the table itself (parameter_table_list).

#include "parameters.hpp"

#include <algorithm>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cartesian_impedance/config.hpp"
#include "cartesian_impedance/error.hpp"
#include "conversions.hpp"
#include "module.hpp"

namespace cartesian_impedance::python {

// ---- Parameters through the parameter table --------------------------------------------------

namespace {

// The table hands out mutable pointers only; reading through them changes nothing.
ci::ParameterField field_of(const ci::Parameters& parameters, const ci::ParameterInfo& info) {
  return info.in(const_cast<ci::Parameters&>(parameters));
}

/// The value of one row: float, str (frames), bool, or for vectors a NumPy array (`as_list`:
/// a list of floats, as in to_dict()).
py::object field_value(const ci::Parameters& parameters, const ci::ParameterInfo& info,
                       bool as_list) {
  const ci::ParameterField field = field_of(parameters, info);
  const auto vector = [as_list](const Eigen::Ref<const Eigen::VectorXd>& values) -> py::object {
    if (!as_list) return vector_array(values);
    py::list list;
    for (Eigen::Index i = 0; i < values.size(); ++i) list.append(values[i]);
    return std::move(list);
  };
  if (auto* value = std::get_if<double*>(&field)) return py::float_(**value);
  if (auto* values = std::get_if<Eigen::Vector3d*>(&field)) return vector(**values);
  if (auto* joints = std::get_if<ci::JointVector*>(&field)) return vector(**joints);
  if (auto* frame = std::get_if<ci::Frame*>(&field)) {
    return py::str(std::string(ci::frame_name(**frame)));
  }
  return py::bool_(*std::get<bool*>(field));
}

bool field_equal(const ci::Parameters& a, const ci::Parameters& b, const ci::ParameterInfo& info) {
  return std::visit(
      [&](auto* left) {
        using Pointer = decltype(left);
        auto* right = std::get<Pointer>(field_of(b, info));
        if constexpr (std::is_same_v<Pointer, ci::JointVector*>) {
          return left->size() == right->size() && *left == *right;
        } else {
          return *left == *right;
        }
      },
      field_of(a, info));
}

/// Stores `value` in the row's field of `parameters` (shape and type checked; ranges are checked
/// by ci::validate() afterwards, which names the element).
void assign_field(ci::Parameters& parameters, const ci::ParameterInfo& info, py::handle value) {
  const std::string name(info.name);
  const ci::ParameterField field = info.in(parameters);
  if (auto* number = std::get_if<double*>(&field)) {
    **number = read_scalar(value, name);
  } else if (auto* axes = std::get_if<Eigen::Vector3d*>(&field)) {
    if (is_array_like_vector(value)) {
      read_vector(value, name, Length{3}, **axes, " (x, y, z) or be one number");
    } else {
      (*axes)->setConstant(read_scalar(value, name));
    }
  } else if (auto* joints = std::get_if<ci::JointVector*>(&field)) {
    **joints = read_one_or_vector(value, name, Length{-1, ci::kMaxJoints});
  } else if (auto* frame = std::get_if<ci::Frame*>(&field)) {
    const std::optional<ci::Frame> given = read_frame(value, name);
    if (!given) throw py::type_error(name + " must be 'base' or 'end_effector', got None");
    **frame = *given;
  } else if (auto* flag = std::get_if<bool*>(&field)) {
    static const py::object* numpy_bool =
        new py::object(py::module_::import("numpy").attr("bool_"));
    if (!PyBool_Check(value.ptr()) && !py::isinstance(value, *numpy_bool)) {
      throw py::type_error(name + " must be True or False, got " + type_name(value));
    }
    **flag = value.cast<bool>();
  }
}

bool is_parameter_group(const std::string& path) {
  const std::string prefix = path + ".";
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    if (info.name.substr(0, prefix.size()) == prefix) return true;
  }
  return false;
}

const ci::ParameterInfo* find_row(std::string_view name) {
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    if (info.name == name) return &info;
  }
  return nullptr;
}

const ci::ParameterInfo& row_for_key(const std::string& path) {
  if (const ci::ParameterInfo* info = find_row(path)) return *info;
  throw ci::Error("unknown parameter '" + path + "'" +
                  (is_parameter_group(path) ? " (it is a group; give its members)" : ""));
}

/// Flattens dotted keys and nested dicts into (row name, value) pairs.
void flatten(py::handle mapping, const std::string& prefix,
             std::vector<std::pair<std::string, py::object>>& out) {
  for (const auto item : py::reinterpret_borrow<py::object>(mapping).attr("items")()) {
    const py::tuple pair(py::reinterpret_borrow<py::object>(item));  // converts, checked
    if (pair.size() != 2) throw py::type_error("items() of a parameter mapping must be pairs");
    if (!py::isinstance<py::str>(pair[0])) {
      throw py::type_error("parameter names must be str, got " + type_name(pair[0]) +
                           (prefix.empty() ? "" : " in '" + prefix + "'"));
    }
    const std::string key = pair[0].cast<std::string>();
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    const py::object value = pair[1];
    if (find_row(path) == nullptr && is_mapping(value) && is_parameter_group(path)) {
      flatten(value, path, out);
    } else {
      out.emplace_back(path, value);
    }
  }
}

/// `base` with every entry of `mapping` applied, validated; `base` itself is not changed.
ci::Parameters parameters_with(const ci::Parameters& base, py::handle mapping) {
  if (!is_mapping(mapping)) {
    throw py::type_error("parameters must be given as a dict (dotted names or nested dicts), got " +
                         type_name(mapping));
  }
  std::vector<std::pair<std::string, py::object>> entries;
  flatten(mapping, "", entries);
  ci::Parameters parameters = base;
  std::vector<std::string> seen;
  for (const auto& [path, value] : entries) {
    const ci::ParameterInfo& info = row_for_key(path);
    if (std::find(seen.begin(), seen.end(), path) != seen.end()) {
      throw ci::Error("parameter '" + path +
                      "' is given twice (as a dotted name and in a nested dict)");
    }
    seen.push_back(path);
    assign_field(parameters, info, value);
  }
  ci::validate(parameters);
  return parameters;
}

py::dict parameters_dict(const ci::Parameters& parameters, bool nested) {
  py::dict result;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    const py::object value = field_value(parameters, info, true);
    if (!nested) {
      result[py::str(std::string(info.name))] = value;
      continue;
    }
    py::dict group = result;
    std::string_view name = info.name;
    for (std::size_t dot; (dot = name.find('.')) != std::string_view::npos;) {
      const py::str key(std::string(name.substr(0, dot)));
      if (!group.contains(key)) group[key] = py::dict();
      group = group[key].cast<py::dict>();
      name.remove_prefix(dot + 1);
    }
    group[py::str(std::string(name))] = value;
  }
  return result;
}

std::string parameters_repr(const ci::Parameters& parameters) {
  const ci::Parameters defaults;
  std::string text;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    if (field_equal(parameters, defaults, info)) continue;
    text += (text.empty() ? "" : ", ") + std::string(py::repr(py::str(std::string(info.name)))) +
            ": " + std::string(py::repr(field_value(parameters, info, true)));
  }
  return text.empty() ? "Parameters()" : "Parameters({" + text + "})";
}

py::list parameter_names() {
  py::list names;
  for (const ci::ParameterInfo& info : ci::parameter_table()) names.append(std::string(info.name));
  return names;
}

py::list parameter_table_list() {
  const ci::Parameters defaults;
  py::list rows;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    const ci::ParameterField field = field_of(defaults, info);
    const char* kind = std::holds_alternative<double*>(field)            ? "number"
                       : std::holds_alternative<Eigen::Vector3d*>(field) ? "xyz"
                       : std::holds_alternative<ci::JointVector*>(field) ? "per_joint"
                       : std::holds_alternative<ci::Frame*>(field)       ? "frame"
                                                                         : "switch";
    py::dict row;
    row["name"] = std::string(info.name);
    row["unit"] = std::string(info.unit);
    row["kind"] = kind;
    row["default"] = field_value(defaults, info, true);
    row["min"] = info.min;
    row["max"] = info.max;
    row["min_exclusive"] = info.min_exclusive;
    row["range"] = std::holds_alternative<ci::Frame*>(field) ? std::string("base, end_effector")
                   : std::holds_alternative<bool*>(field)    ? std::string("true, false")
                                                             : info.range_text();
    row["description"] = std::string(info.description);
    rows.append(row);
  }
  return rows;
}

}  // namespace

ci::Parameters read_parameters(py::handle object) {
  if (object.is_none()) return ci::Parameters{};
  if (py::isinstance<ci::Parameters>(object)) return object.cast<ci::Parameters>();
  if (is_mapping(object)) return parameters_with(ci::Parameters{}, object);
  throw py::type_error("parameters must be a Parameters, a dict or None, got " + type_name(object));
}

void bind_parameters(py::module_& m) {
  // ---- Parameters ----
  py::class_<ci::Parameters>(
      m, "Parameters",
      "Every configurable quantity of the controller, addressed by the dotted names of the "
      "parameter table (parameter_table()), e.g. p['stiffness.translation'] = [800, 800, 800].\n\n"
      "Build from a dict whose keys are dotted names or nested dicts (both accepted, also mixed), "
      "from YAML text or a YAML file; convert back with to_dict() or to_yaml(). Three-axis values "
      "are x, y, z; per-joint values are one number for all joints or one per joint. Every change "
      "is validated (cartesian_impedance.Error names the field, value and range) and a rejected "
      "change leaves the object as it was.")
      .def(py::init([](ParametersLike values) { return read_parameters(values); }),
           py::arg("values") = py::none(),
           "Defaults, or the defaults updated with a dict (dotted names or nested dicts), or a "
           "copy of another Parameters.")
      .def_static(
          "from_dict", [](Mapping values) { return parameters_with(ci::Parameters{}, values); },
          py::arg("values"),
          "The defaults updated with `values` (dotted names or nested dicts). Raises Error for an "
          "unknown name or an invalid value, TypeError/ValueError for a wrong type or shape.")
      .def(
          "to_dict",
          [](const ci::Parameters& parameters, bool nested) {
            return parameters_dict(parameters, nested);
          },
          py::arg("nested") = false,
          "Every parameter: {dotted name: value} (nested=True: nested dicts, as in YAML). "
          "Vectors are lists of floats, frames str, switches bool; from_dict() reads it back.")
      .def(
          "update",
          [](ci::Parameters& parameters, Mapping values) {
            parameters = parameters_with(parameters, values);
          },
          py::arg("values"),
          "Applies a dict of changes (dotted names or nested dicts), all or none.")
      .def_static(
          "from_yaml",
          [](const std::string& text) { return ci::parameters_from_yaml(text, "<yaml>"); },
          py::arg("text"), "Parameters from YAML text (keys not given keep their defaults).")
      .def_static(
          "load", [](PathLike path) { return ci::load_parameters(read_path(path, "path")); },
          py::arg("path"),
          "Parameters from a YAML file (e.g. config/panda.yaml). Raises Error for a missing or "
          "malformed file, an unknown key (named, with its line) or an invalid value.")
      .def("to_yaml", &ci::parameters_to_yaml,
           "Every parameter as YAML text, which from_yaml() reads back to the same values.")
      .def(
          "save",
          [](const ci::Parameters& parameters, PathLike path_object) {
            ci::save_parameters(read_path(path_object, "path"), parameters);
          },
          py::arg("path"), "Writes to_yaml() to a file.")
      .def(
          "__getitem__",
          [](const ci::Parameters& parameters, const std::string& name) {
            return field_value(parameters, row_for_key(name), false);
          },
          py::arg("name"),
          "Value of a dotted name: float, NumPy array (x, y, z or per joint), str (frame) or bool.")
      .def(
          "__setitem__",
          [](ci::Parameters& parameters, const std::string& name, py::object value) {
            ci::Parameters changed = parameters;
            assign_field(changed, row_for_key(name), value);
            ci::validate(changed);
            parameters = changed;
          },
          py::arg("name"), py::arg("value"))
      .def("__contains__",
           [](const ci::Parameters&, const std::string& name) { return find_row(name) != nullptr; })
      .def(
          "keys", [](const ci::Parameters&) { return parameter_names(); },
          "Every dotted name, in the order of the parameter table.")
      .def("__iter__", [](const ci::Parameters&) { return py::iter(parameter_names()); })
      .def("__len__", [](const ci::Parameters&) { return ci::parameter_table().size(); })
      .def(
          "validate",
          [](const ci::Parameters& parameters, int num_joints) {
            ci::validate(parameters, num_joints);
          },
          py::arg("num_joints") = 0,
          "Raises Error unless every value is in range and every per-joint value has 1 or "
          "num_joints entries (0: any count up to MAX_JOINTS).")
      .def(
          "__eq__",
          [](const ci::Parameters& a, py::object other) -> py::object {
            if (!py::isinstance<ci::Parameters>(other))
              return py::reinterpret_borrow<py::object>(Py_NotImplemented);
            const ci::Parameters& b = other.cast<const ci::Parameters&>();
            for (const ci::ParameterInfo& info : ci::parameter_table()) {
              if (!field_equal(a, b, info)) return py::bool_(false);
            }
            return py::bool_(true);
          },
          py::is_operator())
      .def("copy", [](const ci::Parameters& parameters) { return parameters; })
      .def("__copy__", [](const ci::Parameters& parameters) { return parameters; })
      .def("__deepcopy__", [](const ci::Parameters& parameters, py::handle) { return parameters; })
      .def("__repr__", &parameters_repr,
           "Shows the values that differ from the defaults, as a dict Parameters() accepts.")
      .def_static("table", &parameter_table_list,
                  "The parameter table: one dict per parameter (name, unit, kind, default, min, "
                  "max, min_exclusive, range, description).")
      .def(py::pickle(
          [](const ci::Parameters& p) { return parameters_dict(p, false); },
          [](const py::dict& state) { return parameters_with(ci::Parameters{}, state); }));

  m.def("parameter_table", &parameter_table_list,
        "The parameter table: one dict per parameter (name, unit, kind, default, min, max, "
        "min_exclusive, range, description), in documentation order.");
  m.def("parameter_table_markdown", &ci::parameter_table_markdown,
        "The parameter table as Markdown, as in the README.");
  m.def(
      "load_parameters", [](PathLike path) { return ci::load_parameters(read_path(path, "path")); },
      py::arg("path"), "Same as Parameters.load(path).");
}

}  // namespace cartesian_impedance::python
