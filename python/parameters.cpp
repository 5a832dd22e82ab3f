// Python bindings of Parameters and the parameter table: the Python adapter of the library's one
// parameter decoder (cartesian_impedance/core/parameter_tree.hpp), as the YAML loader and the ROS
// parameter reader are. Python values become a ci::ParameterValue tree (to_value) that
// ci::decode_parameters() / ci::assign_parameter() decode; values leave through
// ci::encode_parameter(s) (to_python). Every message about a value's type, shape or range is the
// decoder's; only what Python itself brings (keys that are not str, objects that are no parameter
// value at all) is checked here.

#include "parameters.hpp"

#include <string>
#include <string_view>
#include <utility>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameter_tree.hpp"
#include "conversions.hpp"
#include "module.hpp"

namespace cartesian_impedance::python {

namespace {

// numpy.<name>, never destroyed (a static py::object would be released after the interpreter).
const py::object& numpy_attribute(const char* name) {
  return *new py::object(py::module_::import("numpy").attr(name));
}

std::string child_path(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

/// `object` as the decoder's value; `path` names it in the messages of the checks made here.
/// `guard` bounds the recursion: a list or dict that contains itself, or is nested without end,
/// is refused by path (ci::ParameterTreeGuard) before the C stack runs out.
ci::ParameterValue to_value(py::handle object, const std::string& path,
                            ci::ParameterTreeGuard& guard) {
  static const py::object& generic = numpy_attribute("generic");
  static const py::object& asarray = numpy_attribute("asarray");
  PyObject* pointer = object.ptr();
  guard.count(path);
  if (object.is_none()) return {};
  if (PyBool_Check(pointer)) return ci::ParameterValue::boolean(pointer == Py_True);
  if (py::isinstance<ci::Frame>(object)) {
    return ci::ParameterValue::string(std::string(ci::frame_name(object.cast<ci::Frame>())));
  }
  if (PyFloat_Check(pointer)) return ci::ParameterValue::number(PyFloat_AS_DOUBLE(pointer));
  if (PyLong_Check(pointer)) {
    const double value = PyLong_AsDouble(pointer);
    if (value == -1.0 && PyErr_Occurred()) {
      if (!PyErr_ExceptionMatches(PyExc_OverflowError)) throw py::error_already_set();
      PyErr_Clear();
      const std::string text = py::str(object);
      return ci::ParameterValue::too_large(text, text[0] == '-');
    }
    return ci::ParameterValue::number(value);
  }
  if (py::isinstance<py::str>(object)) {
    return ci::ParameterValue::string(object.cast<std::string>());
  }
  if (is_mapping(object)) {
    const ci::ParameterTreeGuard::Level level = guard.enter(pointer, path);
    ci::ParameterMap members;
    for (const auto item : py::reinterpret_borrow<py::object>(object).attr("items")()) {
      const py::tuple pair(py::reinterpret_borrow<py::object>(item));  // converts, checked
      if (pair.size() != 2) throw py::type_error("items() of a parameter mapping must be pairs");
      if (!py::isinstance<py::str>(pair[0])) {
        throw py::type_error("parameter names must be str, got " + type_name(pair[0]) +
                             (path.empty() ? "" : " in '" + path + "'"));
      }
      const std::string key = pair[0].cast<std::string>();
      const std::string child = child_path(path, key);
      guard.count(child);
      members.push_back({key, to_value(pair[1], child, guard), {}});
    }
    return ci::ParameterValue::map(std::move(members));
  }
  if (is_sequence(object)) {
    const ci::ParameterTreeGuard::Level level = guard.enter(pointer, path);
    ci::ParameterList items;
    for (const py::handle item : py::reinterpret_borrow<py::sequence>(object)) {
      items.push_back(to_value(item, path + "[" + std::to_string(items.size()) + "]", guard));
    }
    return ci::ParameterValue::list(std::move(items));
  }
  if (py::isinstance<py::array>(object) || py::isinstance(object, generic)) {
    py::array array = asarray(object);
    const char kind = array.dtype().kind();
    if (kind != 'c' && kind != 'O') {
      // 0-d: the Python scalar; n-d: nested Python lists (long double becomes float first, else
      // its item() would be a NumPy scalar again), bounded by the guard like any list.
      if (kind == 'f') array = array.attr("astype")("float64");
      return to_value(array.ndim() == 0 ? array.attr("item")() : array.attr("tolist")(), path,
                      guard);
    }
    throw py::type_error(path + " must be real numbers, got dtype " +
                         std::string(py::str(array.dtype())));
  }
  throw py::type_error(path + " must be a number, a bool, a str, a list, a dict or None, got " +
                       type_name(object));
}

/// `object` as the decoder's value, in a tree of its own (one guard).
ci::ParameterValue to_value(py::handle object, const std::string& path) {
  ci::ParameterTreeGuard guard;
  return to_value(object, path, guard);
}

/// `value` in Python: float, bool, str, None, dict; lists as NumPy arrays or (`lists`) lists of
/// floats.
py::object to_python(const ci::ParameterValue& value, bool lists) {
  using Kind = ci::ParameterValue::Kind;
  switch (value.kind()) {
    case Kind::empty:
      return py::none();
    case Kind::number:
      return py::float_(value.as_number());
    case Kind::boolean:
      return py::bool_(value.as_boolean());
    case Kind::string:
      return py::str(value.as_string());
    case Kind::list: {
      py::list items;
      for (const ci::ParameterValue& item : value.as_list()) items.append(to_python(item, lists));
      return lists ? py::object(std::move(items)) : py::object(py::array_t<double>(items));
    }
    case Kind::map:
      break;
  }
  py::dict members;
  for (const ci::ParameterMember& member : value.as_map()) {
    members[py::str(member.key)] = to_python(member.value, lists);
  }
  return std::move(members);
}

/// Runs `decode`; the decoder's errors about a value's type (or its absence) become TypeError,
/// the others stay cartesian_impedance.Error (a ValueError).
template <typename Decode>
auto decoding(Decode&& decode) {
  try {
    return decode();
  } catch (const ci::ParameterError& error) {
    using Reason = ci::ParameterError::Reason;
    if (error.reason() == Reason::wrong_type || error.reason() == Reason::no_value) {
      throw py::type_error(error.what());
    }
    throw;
  }
}

/// `base` with every entry of `mapping` applied, validated; `base` itself is not changed.
ci::Parameters parameters_with(const ci::Parameters& base, py::handle mapping) {
  if (!is_mapping(mapping)) {
    throw py::type_error("parameters must be given as a dict (dotted names or nested dicts), got " +
                         type_name(mapping));
  }
  return decoding([&] { return ci::decode_parameters(to_value(mapping, ""), base); });
}

py::object parameter_value(const ci::Parameters& parameters, const ci::ParameterInfo& row,
                           bool lists) {
  return to_python(ci::encode_parameter(parameters, row), lists);
}

py::dict parameters_dict(const ci::Parameters& parameters, bool nested) {
  const ci::KeyLayout layout = nested ? ci::KeyLayout::nested : ci::KeyLayout::dotted;
  return to_python(ci::encode_parameters(parameters, layout), true).cast<py::dict>();
}

bool field_equal(const ci::Parameters& a, const ci::Parameters& b, const ci::ParameterInfo& row) {
  return ci::encode_parameter(a, row) == ci::encode_parameter(b, row);
}

std::string parameters_repr(const ci::Parameters& parameters) {
  const ci::Parameters defaults;
  std::string text;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    if (field_equal(parameters, defaults, info)) continue;
    text += (text.empty() ? "" : ", ") + std::string(py::repr(py::str(std::string(info.name)))) +
            ": " + std::string(py::repr(parameter_value(parameters, info, true)));
  }
  return text.empty() ? "Parameters()" : "Parameters({" + text + "})";
}

py::list parameter_names() {
  py::list names;
  for (const ci::ParameterInfo& info : ci::parameter_table()) names.append(std::string(info.name));
  return names;
}

py::list parameter_table_list() {
  ci::Parameters defaults;
  py::list rows;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    const ci::ParameterField field = info.in(defaults);
    const char* kind = std::holds_alternative<double*>(field)            ? "number"
                       : std::holds_alternative<Eigen::Vector3d*>(field) ? "xyz"
                       : std::holds_alternative<ci::JointVector*>(field) ? "per_joint"
                       : std::holds_alternative<ci::Frame*>(field)       ? "frame"
                       : !ci::choice_names(field).empty()                ? "choice"
                                                                         : "switch";
    py::dict row;
    row["name"] = std::string(info.name);
    row["unit"] = std::string(info.unit);
    row["kind"] = kind;
    row["default"] = parameter_value(defaults, info, true);
    row["min"] = info.min;
    row["max"] = info.max;
    row["min_exclusive"] = info.min_exclusive;
    std::string choices;
    for (const std::string_view name : ci::choice_names(field)) {
      choices += (choices.empty() ? "" : ", ") + std::string(name);
    }
    row["range"] = !choices.empty()                       ? choices
                   : std::holds_alternative<bool*>(field) ? std::string("true, false")
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

ci::ParameterUpdate read_parameter_update(py::handle mapping, const ci::Parameters& base) {
  if (!is_mapping(mapping)) {
    throw py::type_error(
        "parameters to update must be given as a dict (dotted names or nested "
        "dicts), got " +
        type_name(mapping));
  }
  return decoding([&] { return ci::decode_parameter_update(to_value(mapping, ""), base); });
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
          "The defaults updated with `values` (dotted names or nested dicts). Raises TypeError for "
          "a value of the wrong type or None, Error for an unknown name, a wrong shape or a value "
          "out of range, with the messages YAML gets.")
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
          "malformed file, one that is not a regular file (a FIFO, /dev/zero) or is over 16 MiB "
          "(LoadError), an unknown key (named, with its line) or an invalid value.")
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
            return parameter_value(parameters, ci::parameter_info(name), false);
          },
          py::arg("name"),
          "Value of a dotted name: float, NumPy array (x, y, z or per joint), str (frame) or bool.")
      .def(
          "__setitem__",
          [](ci::Parameters& parameters, const std::string& name, py::object value) {
            ci::Parameters changed = parameters;
            decoding([&] { ci::assign_parameter(changed, name, to_value(value, name)); });
            ci::validate(changed);
            parameters = changed;
          },
          py::arg("name"), py::arg("value"))
      .def("__contains__",
           [](const ci::Parameters&, const std::string& name) {
             return ci::find_parameter(name) != nullptr;
           })
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
