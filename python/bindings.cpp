// Python bindings of the cartesian_impedance library: a thin shell that converts and delegates.
//
// Every array argument goes through the conversion helpers at the top of this file, which check
// the type (any real dtype is converted to float64; bool, complex, object and string arrays are
// rejected with TypeError) and the shape (ValueError naming the argument and the expected shape)
// before the library sees it. The library then validates the values and throws
// cartesian_impedance::Error, which Python sees as cartesian_impedance.Error (a ValueError) with
// the same message. Arrays leave as fresh NumPy copies, so nothing in Python aliases the library's
// storage.
//
// Threads: ControlLoop commands (the setters, execute_trajectory) may come from any Python thread,
// as in C++. Simulation.run() releases the GIL while it steps; the simulation and the loop's cycle
// (start, step, state) are claimed for that time, so another thread touching them gets a
// RuntimeError instead of a data race.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "cartesian_impedance/config.hpp"
#include "cartesian_impedance/control_loop.hpp"
#include "cartesian_impedance/controller.hpp"
#include "cartesian_impedance/error.hpp"
#include "cartesian_impedance/parameters.hpp"
#include "cartesian_impedance/robot_model.hpp"
#include "cartesian_impedance/types.hpp"
#ifdef CARTESIAN_IMPEDANCE_PYTHON_SIM
#include "cartesian_impedance/sim/simulation.hpp"
#endif

namespace py = pybind11;
namespace ci = cartesian_impedance;

namespace {

// ---- Python -> Eigen ------------------------------------------------------------------------

std::string type_name(py::handle object) {
  return Py_TYPE(object.ptr())->tp_name;
}

std::string shape_text(const py::array& array) {
  std::string text = "(";
  for (py::ssize_t i = 0; i < array.ndim(); ++i) {
    if (i > 0) text += ", ";
    text += std::to_string(array.shape(i));
  }
  return text + (array.ndim() == 1 ? ",)" : ")");
}

const py::object& numpy_asarray() {
  // Never destroyed: a static py::object would be released after the interpreter has gone.
  static const py::object* function = new py::object(py::module_::import("numpy").attr("asarray"));
  return *function;
}

bool is_sequence(py::handle object) {
  return PyList_Check(object.ptr()) || PyTuple_Check(object.ptr());
}

bool is_mapping(py::handle object) {
  static const py::object* mapping =
      new py::object(py::module_::import("collections.abc").attr("Mapping"));
  return PyDict_Check(object.ptr()) || py::isinstance(object, *mapping);
}

/// `object` as a float64 NumPy array, without a copy if it is one already. Integer and float
/// dtypes are converted; bool, complex, object, string and other dtypes raise TypeError.
py::array_t<double> real_array(py::handle object, std::string_view name) {
  if (py::isinstance<py::array_t<double>>(object)) {
    return py::reinterpret_borrow<py::array_t<double>>(object);
  }
  py::array array;
  if (py::isinstance<py::array>(object)) {
    array = py::reinterpret_borrow<py::array>(object);
  } else {
    if (object.is_none() || py::isinstance<py::str>(object) || py::isinstance<py::bytes>(object)) {
      throw py::type_error(std::string(name) + " must be real numbers, got " + type_name(object));
    }
    try {
      array = numpy_asarray()(object);
    } catch (py::error_already_set& error) {
      throw py::value_error(std::string(name) +
                            " cannot be read as an array of numbers: " + error.what());
    }
  }
  const char kind = array.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::type_error(
        std::string(name) + " must be real numbers (an integer or float dtype), got " +
        (py::isinstance<py::array>(object) ? "an array of dtype " : "values of dtype ") +
        std::string(py::str(array.dtype())));
  }
  return py::array_t<double>::ensure(array);
}

/// Accepted length of a vector argument: exactly `size` entries, or any of 1..max_size if size < 0.
struct Length {
  Eigen::Index size = -1;
  Eigen::Index max_size = ci::kMaxJoints;
};

constexpr Eigen::Index kUnbounded = std::numeric_limits<Eigen::Index>::max();

std::string expected_shape(Length length) {
  if (length.size >= 0) return "(" + std::to_string(length.size) + ",)";
  if (length.max_size == kUnbounded) return "(n,) with n >= 1";
  return "(n,) with 1 <= n <= " + std::to_string(length.max_size);
}

bool length_ok(Eigen::Index size, Length length) {
  return length.size >= 0 ? size == length.size : size >= 1 && size <= length.max_size;
}

/// Reads a vector argument into `out` (resized). A list or tuple of Python floats and ints is read
/// directly; anything else through NumPy. `alternative` extends the message ("or one number").
template <typename Vector>
void read_vector(py::handle object, std::string_view name, Length length, Vector& out,
                 std::string_view alternative = {}) {
  const auto fail = [&](const std::string& got) {
    throw py::value_error(std::string(name) + " must have shape " + expected_shape(length) +
                          std::string(alternative) + ", got " + got);
  };
  if (is_sequence(object)) {
    PyObject* sequence = object.ptr();
    const Py_ssize_t size = PySequence_Fast_GET_SIZE(sequence);
    PyObject** items = PySequence_Fast_ITEMS(sequence);
    // Floats (NumPy's float64 scalars are a subclass) and ints, not bools (a subclass of int).
    bool plain = true;
    for (Py_ssize_t i = 0; i < size && plain; ++i) {
      plain = PyFloat_Check(items[i]) || (PyLong_Check(items[i]) && !PyBool_Check(items[i]));
    }
    if (plain) {
      if (!length_ok(size, length)) fail("length " + std::to_string(size));
      out.resize(size);
      for (Py_ssize_t i = 0; i < size; ++i) {
        if (PyFloat_Check(items[i])) {
          out[i] = PyFloat_AS_DOUBLE(items[i]);
        } else {
          out[i] = PyLong_AsDouble(items[i]);
          if (out[i] == -1.0 && PyErr_Occurred()) throw py::error_already_set();
        }
      }
      return;
    }
  }
  const py::array_t<double> array = real_array(object, name);
  if (array.ndim() != 1 || !length_ok(array.shape(0), length)) fail("shape " + shape_text(array));
  const auto view = array.unchecked<1>();
  out.resize(array.shape(0));
  for (py::ssize_t i = 0; i < array.shape(0); ++i) out[i] = view(i);
}

/// Reads a 2-D argument of rows x cols (a Length each; `square` requires rows == cols).
template <typename Matrix>
void read_matrix(py::handle object, std::string_view name, Length rows, Length cols, Matrix& out,
                 bool square = false, const char* row_symbol = "n") {
  const py::array_t<double> array = real_array(object, name);
  const bool ok = array.ndim() == 2 && length_ok(array.shape(0), rows) &&
                  length_ok(array.shape(1), cols) && (!square || array.shape(0) == array.shape(1));
  if (!ok) {
    const auto side = [](Length length, const char* symbol) {
      return length.size >= 0 ? std::to_string(length.size) : std::string(symbol);
    };
    std::string expected =
        "(" + side(rows, row_symbol) + ", " + side(cols, square ? row_symbol : "n") + ")";
    if ((rows.size < 0 && rows.max_size != kUnbounded) || cols.size < 0) {
      expected += " with 1 <= n <= " + std::to_string(ci::kMaxJoints);
    }
    throw py::value_error(std::string(name) + " must have shape " + expected + ", got shape " +
                          shape_text(array));
  }
  const auto view = array.unchecked<2>();
  out.resize(array.shape(0), array.shape(1));
  for (py::ssize_t i = 0; i < array.shape(0); ++i) {
    for (py::ssize_t j = 0; j < array.shape(1); ++j) out(i, j) = view(i, j);
  }
}

bool is_array_like_vector(py::handle object) {
  return is_sequence(object) || (py::isinstance<py::array>(object) &&
                                 py::reinterpret_borrow<py::array>(object).ndim() > 0);
}

/// A real number: Python float or int, a NumPy real scalar or a 0-d array (not bool).
double read_scalar(py::handle object, std::string_view name) {
  PyObject* pointer = object.ptr();
  if (PyFloat_Check(pointer)) return PyFloat_AS_DOUBLE(pointer);
  if (PyBool_Check(pointer)) {
    throw py::type_error(std::string(name) + " must be a real number, got bool");
  }
  if (PyLong_Check(pointer)) {
    const double value = PyLong_AsDouble(pointer);
    if (value == -1.0 && PyErr_Occurred()) throw py::error_already_set();
    return value;
  }
  if (is_sequence(object)) {
    throw py::type_error(std::string(name) + " must be a real number, got " + type_name(object));
  }
  const py::array_t<double> array = real_array(object, name);
  if (array.ndim() != 0) {
    throw py::value_error(std::string(name) + " must be a single number, got shape " +
                          shape_text(array));
  }
  return *array.data();
}

/// One number for all entries or a vector (per-joint fields, nullspace stiffness).
Eigen::VectorXd read_one_or_vector(py::handle object, std::string_view name, Length length) {
  Eigen::VectorXd values;
  if (is_array_like_vector(object)) {
    read_vector(object, name, length, values, " or be one number");
  } else {
    values = Eigen::VectorXd::Constant(1, read_scalar(object, name));
  }
  return values;
}

std::string read_path(py::handle object, std::string_view name) {
  static const py::object* fspath = new py::object(py::module_::import("os").attr("fspath"));
  py::object path;
  try {
    path = (*fspath)(object);
  } catch (py::error_already_set&) {
    throw py::type_error(std::string(name) + " must be a str or os.PathLike, got " +
                         type_name(object));
  }
  return path.cast<std::string>();
}

std::optional<ci::Frame> read_frame(py::handle object, std::string_view name) {
  if (object.is_none()) return std::nullopt;
  if (py::isinstance<ci::Frame>(object)) return object.cast<ci::Frame>();
  if (py::isinstance<py::str>(object)) {
    return ci::frame_from_name(name, object.cast<std::string>());
  }
  throw py::type_error(std::string(name) +
                       " must be 'base', 'end_effector', a Frame or None, got " +
                       type_name(object));
}

// Rotation matrices converted from 4x4 transforms must be this close to orthonormal, the same
// tolerance the library allows a quaternion's norm: a transform rounded to a few digits passes,
// a scaled or sheared one does not.
constexpr double kRotationTolerance = ci::kQuaternionNormTolerance;

ci::Pose pose_from_matrix(const Eigen::Matrix4d& matrix, std::string_view name) {
  const std::string field(name);
  if (!matrix.allFinite()) throw ci::Error(field + ": the 4x4 transform has a non-finite entry");
  const Eigen::RowVector4d last_row = matrix.row(3);
  if ((last_row - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    std::ostringstream text;
    text << field << ": the last row of a 4x4 homogeneous transform must be [0, 0, 0, 1], got ["
         << ci::format_number(last_row[0]) << ", " << ci::format_number(last_row[1]) << ", "
         << ci::format_number(last_row[2]) << ", " << ci::format_number(last_row[3]) << "]";
    throw ci::Error(text.str());
  }
  const Eigen::Matrix3d rotation = matrix.topLeftCorner<3, 3>();
  const double deviation =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (deviation > kRotationTolerance || rotation.determinant() <= 0.0) {
    throw ci::Error(
        field + ": the rotation part of the 4x4 transform is not a rotation (max |R^T R - I| = " +
        ci::format_number(deviation) + ", det R = " + ci::format_number(rotation.determinant()) +
        "; tolerance " + ci::format_number(kRotationTolerance) + ")");
  }
  ci::Pose pose;
  pose.position = matrix.topRightCorner<3, 1>();
  pose.orientation = Eigen::Quaterniond(rotation).normalized();
  return pose;
}

Eigen::Quaterniond quaternion_xyzw(py::handle object, std::string_view name) {
  Eigen::Vector4d xyzw;
  read_vector(object, name, Length{4}, xyzw);
  // Not normalised here: the library checks the norm (within 1e-3) wherever a pose is commanded.
  return Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
}

/// A pose given as a Pose, a pair (position (3,), quaternion x, y, z, w (4,)) or a 4x4
/// homogeneous transform.
ci::Pose read_pose(py::handle object, std::string_view name) {
  if (py::isinstance<ci::Pose>(object)) return object.cast<ci::Pose>();
  const std::string field(name);
  if (is_sequence(object) && PySequence_Fast_GET_SIZE(object.ptr()) == 2) {
    PyObject** items = PySequence_Fast_ITEMS(object.ptr());
    ci::Pose pose;
    read_vector(py::handle(items[0]), field + " position", Length{3}, pose.position);
    pose.orientation = quaternion_xyzw(py::handle(items[1]), field + " quaternion (x, y, z, w)");
    return pose;
  }
  const std::string forms =
      " must be a Pose, a pair (position (3,) [m], quaternion (4,) in the order x, y, z, w) or a "
      "4x4 homogeneous transform";
  if (!is_sequence(object) && !py::isinstance<py::array>(object)) {
    throw py::type_error(field + forms + ", got " + type_name(object));
  }
  const py::array_t<double> array = real_array(object, name);
  if (array.ndim() != 2 || array.shape(0) != 4 || array.shape(1) != 4) {
    throw py::value_error(field + forms + ", got shape " + shape_text(array));
  }
  Eigen::Matrix4d matrix;
  read_matrix(array, name, Length{4}, Length{4}, matrix);
  return pose_from_matrix(matrix, name);
}

// ---- Eigen -> Python (always copies) ---------------------------------------------------------

py::array_t<double> vector_array(const Eigen::Ref<const Eigen::VectorXd>& vector) {
  py::array_t<double> array(vector.size());
  std::copy(vector.data(), vector.data() + vector.size(), array.mutable_data());
  return array;
}

py::array_t<double> matrix_array(const Eigen::Ref<const Eigen::MatrixXd>& matrix) {
  py::array_t<double> array({matrix.rows(), matrix.cols()});
  auto view = array.mutable_unchecked<2>();
  for (Eigen::Index i = 0; i < matrix.rows(); ++i) {
    for (Eigen::Index j = 0; j < matrix.cols(); ++j) view(i, j) = matrix(i, j);
  }
  return array;
}

py::array_t<double> xyzw_array(const Eigen::Quaterniond& quaternion) {
  return vector_array(quaternion.coeffs());  // Eigen stores x, y, z, w
}

py::object optional_array(const ci::JointVector& vector) {
  if (vector.size() == 0) return py::none();
  return vector_array(vector);
}

Eigen::Matrix4d pose_matrix(const ci::Pose& pose) {
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  matrix.topLeftCorner<3, 3>() = pose.orientation.normalized().toRotationMatrix();
  matrix.topRightCorner<3, 1>() = pose.position;
  return matrix;
}

std::string numbers_text(const Eigen::Ref<const Eigen::VectorXd>& values) {
  std::string text = "[";
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    text += (i > 0 ? ", " : "") + ci::format_number(values[i]);
  }
  return text + "]";
}

std::string pose_repr(const ci::Pose& pose) {
  return "Pose(position=" + numbers_text(pose.position) +
         ", orientation_xyzw=" + numbers_text(pose.orientation.coeffs()) + ")";
}

// ---- Parameters through the parameter table --------------------------------------------------

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

/// A Parameters object, a dict (dotted names or nested) or None (the defaults).
ci::Parameters read_parameters(py::handle object) {
  if (object.is_none()) return ci::Parameters{};
  if (py::isinstance<ci::Parameters>(object)) return object.cast<ci::Parameters>();
  if (is_mapping(object)) return parameters_with(ci::Parameters{}, object);
  throw py::type_error("parameters must be a Parameters, a dict or None, got " + type_name(object));
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

// ---- Wrappers that own what Python needs beside the library object ---------------------------

/// Marks an object as in use by a call that has released the GIL; other threads then get a
/// RuntimeError instead of racing with it.
class Claim {
 public:
  Claim(std::atomic<bool>& flag, const char* what) : flag_(flag) {
    if (flag_.exchange(true)) {
      throw std::runtime_error(std::string(what) +
                               " is in use by Simulation.run() in another thread");
    }
  }
  ~Claim() { flag_.store(false); }
  Claim(const Claim&) = delete;
  Claim& operator=(const Claim&) = delete;

 private:
  std::atomic<bool>& flag_;
};

void check_free(const std::atomic<bool>& flag, const char* what) {
  if (flag.load()) {
    throw std::runtime_error(std::string(what) +
                             " is in use by Simulation.run() in another thread");
  }
}

/// RobotModel plus a workspace for compute() from Python.
struct Model {
  explicit Model(ci::RobotModel loaded) : model(std::move(loaded)), workspace(model) {}
  ci::RobotModel model;
  ci::ModelWorkspace workspace;
};

Eigen::Isometry3d isometry(const ci::Pose& pose) {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = pose.orientation.toRotationMatrix();
  transform.translation() = pose.position;
  return transform;
}

std::unique_ptr<Model> load_model(bool from_file, const std::string& source,
                                  const std::string& base_link, const std::string& tip_link,
                                  py::handle tool, py::handle gravity) {
  const Eigen::Isometry3d tool_transform =
      tool.is_none() ? Eigen::Isometry3d::Identity() : isometry(read_pose(tool, "tool"));
  const auto load = [&](auto&&... gravity_argument) {
    return from_file ? ci::RobotModel::from_urdf_file(source, base_link, tip_link, tool_transform,
                                                      gravity_argument...)
                     : ci::RobotModel::from_urdf_string(source, base_link, tip_link, tool_transform,
                                                        gravity_argument...);
  };
  if (gravity.is_none()) return std::make_unique<Model>(load());
  Eigen::Vector3d gravity_base;
  read_vector(gravity, "gravity", Length{3}, gravity_base);
  return std::make_unique<Model>(load(gravity_base));
}

ci::JointVector finite_joints(py::handle object, std::string_view name, int num_joints) {
  ci::JointVector values;
  read_vector(object, name, Length{num_joints}, values);
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      throw ci::Error(std::string(name) + "[" + std::to_string(i) +
                      "] = " + ci::format_number(values[i]) + " is not finite");
    }
  }
  return values;
}

/// ControlLoop plus the Python model object it was made from and the run() claim.
class Loop {
 public:
  Loop(py::object model_object, const ci::Parameters& parameters, ci::LoopCapacity capacity)
      : model_object(std::move(model_object)),
        loop(this->model_object.cast<Model&>().model, parameters, capacity) {}

  /// The loop for cycle-thread calls (start, step, state): refused while run() uses it.
  ci::ControlLoop& cycle() {
    check_free(running, "this ControlLoop");
    return loop;
  }

  py::object model_object;
  ci::ControlLoop loop;
  std::atomic<bool> running{false};
};

std::string trajectory_text(const ci::TrajectoryProgress& progress) {
  std::string text = ci::to_string(progress.state);
  if (progress.state != ci::TrajectoryState::idle) {
    text += " (id " + std::to_string(progress.id) + ", " + ci::format_number(progress.time) +
            " of " + ci::format_number(progress.duration) + " s)";
  }
  return text;
}

#ifdef CARTESIAN_IMPEDANCE_PYTHON_SIM
/// Simulation plus the run() claim.
struct Sim {
  explicit Sim(ci::sim::Simulation loaded) : sim(std::move(loaded)) {}
  ci::sim::Simulation& get() {
    check_free(running, "this Simulation");
    return sim;
  }
  ci::sim::Simulation sim;
  std::atomic<bool> running{false};
};

ci::sim::SimulationOptions simulation_options(py::handle timestep, bool gravity_compensation,
                                              const std::string& keyframe,
                                              const std::optional<std::vector<std::string>>& names,
                                              bool multi_point_contacts) {
  ci::sim::SimulationOptions options;
  options.timestep = read_scalar(timestep, "timestep");
  options.gravity_compensation = gravity_compensation;
  options.keyframe = keyframe;
  if (names) options.joint_names = *names;
  options.multi_point_contacts = multi_point_contacts;
  return options;
}

// Simulation.run() takes the GIL back this often to let Ctrl+C (KeyboardInterrupt) through.
constexpr std::int64_t kSignalCheckSteps = 1000;
#endif

// ---- Docstrings shared by several functions --------------------------------------------------

constexpr const char* kPoseForms =
    "A pose is a Pose, a pair (position (3,) [m], quaternion (4,) in the order x, y, z, w) or a "
    "4x4 homogeneous transform, expressed in the base frame.";

// ---- Argument types: any Python object, converted by the helpers above ----------------------
// They only name what is expected in the signatures pybind11 writes into the docstrings (a
// py::handle shows as "handle").

#define CARTESIAN_IMPEDANCE_ARGUMENT(Type)          \
  class Type : public py::object {                  \
   public:                                          \
    using py::object::object;                       \
    static bool check_(py::handle) { return true; } \
  };
CARTESIAN_IMPEDANCE_ARGUMENT(ArrayLike)
CARTESIAN_IMPEDANCE_ARGUMENT(Real)
CARTESIAN_IMPEDANCE_ARGUMENT(PoseLike)
CARTESIAN_IMPEDANCE_ARGUMENT(FrameLike)
CARTESIAN_IMPEDANCE_ARGUMENT(PathLike)
CARTESIAN_IMPEDANCE_ARGUMENT(ParametersLike)
CARTESIAN_IMPEDANCE_ARGUMENT(Mapping)
#undef CARTESIAN_IMPEDANCE_ARGUMENT

}  // namespace

namespace pybind11::detail {
template <>
struct handle_type_name<ArrayLike> {
  static constexpr auto name = const_name("ArrayLike");
};
template <>
struct handle_type_name<Real> {
  static constexpr auto name = const_name("float");
};
template <>
struct handle_type_name<PoseLike> {
  static constexpr auto name = const_name("Pose | tuple[ArrayLike, ArrayLike] | ArrayLike");
};
template <>
struct handle_type_name<FrameLike> {
  static constexpr auto name = const_name("str | Frame | None");
};
template <>
struct handle_type_name<PathLike> {
  static constexpr auto name = const_name("str | os.PathLike");
};
template <>
struct handle_type_name<ParametersLike> {
  static constexpr auto name = const_name("Parameters | dict | None");
};
template <>
struct handle_type_name<Mapping> {
  static constexpr auto name = const_name("dict");
};
}  // namespace pybind11::detail

namespace {

/// Binds the command setters CartesianImpedanceController and ControlLoop share. `target(self)`
/// gives the C++ object; `verb` starts each docstring ("Sets" for the controller, which applies
/// at once, "Queues" for the loop, which applies at its next step).
template <typename Self, typename Target>
void def_commands(py::class_<Self>& binding, Target& (*target)(Self&), const std::string& verb) {
  // pybind11 copies docstrings, so temporaries (alive until the end of the statement) will do.
  const auto doc = [verb](const std::string& text) { return verb + " " + text; };
  const std::string ends_trajectory = verb == "Queues" ? " Ends a running trajectory." : "";
  binding
      .def(
          "set_reference_pose",
          [target](Self& self, PoseLike pose) {
            target(self).set_reference_pose(read_pose(pose, "pose"));
          },
          py::arg("pose"),
          doc(std::string("the reference pose T_base_ref. ") + kPoseForms +
              " The quaternion must have unit norm within 1e-3." + ends_trajectory)
              .c_str())
      .def(
          "set_stiffness",
          [target](Self& self, ArrayLike stiffness, FrameLike frame) {
            const std::optional<ci::Frame> in = read_frame(frame, "frame");
            if (is_sequence(stiffness) || py::isinstance<py::array>(stiffness)) {
              const py::array_t<double> array = real_array(stiffness, "stiffness");
              if (array.ndim() == 2) {
                ci::Matrix6d matrix;
                read_matrix(array, "stiffness", Length{6}, Length{6}, matrix);
                return target(self).set_stiffness_matrix(matrix, in);
              }
            }
            ci::Vector6d diagonal;
            read_vector(stiffness, "stiffness", Length{6}, diagonal, " or (6, 6)");
            target(self).set_stiffness(diagonal, in);
          },
          py::arg("stiffness"), py::arg("frame") = py::none(),
          doc("the stiffness: diagonal (6,) [N/m x3, Nm/rad x3] or a full symmetric positive "
              "semi-definite (6, 6) matrix, in `frame` ('base' or 'end_effector'; default: the "
              "configured stiffness.frame). Values beyond limits.stiffness.* are saturated.")
              .c_str())
      .def(
          "set_damping_ratio",
          [target](Self& self, ArrayLike ratio) {
            ci::Vector6d values;
            read_vector(ratio, "damping_ratio", Length{6}, values);
            target(self).set_damping_ratio(values);
          },
          py::arg("damping_ratio"),
          doc("the damping ratio per axis of the stiffness frame (6,) [-].").c_str())
      .def(
          "set_nullspace_target",
          [target](Self& self, ArrayLike q) {
            ci::JointVector values;
            read_vector(q, "q_desired", Length{target(self).num_joints()}, values);
            target(self).set_nullspace_target(values);
          },
          py::arg("q_desired"),
          doc("the nullspace target configuration (n,) [rad]." + ends_trajectory).c_str())
      .def(
          "set_nullspace_stiffness",
          [target](Self& self, ArrayLike k) {
            target(self).set_nullspace_stiffness(read_one_or_vector(k, "stiffness", Length{}));
          },
          py::arg("stiffness"),
          doc("the nullspace stiffness [Nm/rad]: one number or (n,).").c_str())
      .def(
          "set_nullspace_damping_ratio",
          [target](Self& self, Real zeta) {
            target(self).set_nullspace_damping_ratio(read_scalar(zeta, "damping_ratio"));
          },
          py::arg("damping_ratio"), doc("the nullspace damping ratio [-].").c_str())
      .def(
          "set_wrench",
          [target](Self& self, ArrayLike wrench, FrameLike frame) {
            ci::Vector6d values;
            read_vector(wrench, "wrench", Length{6}, values);
            target(self).set_wrench(values, read_frame(frame, "frame"));
          },
          py::arg("wrench"), py::arg("frame") = py::none(),
          doc("the commanded wrench [force; torque] (6,) [N; Nm] on the environment, in `frame` "
              "('base' or 'end_effector'; default: the configured wrench.frame).")
              .c_str());
}
}  // namespace

PYBIND11_MODULE(cartesian_impedance, m) {
  m.doc() =
      "Cartesian impedance control of torque-controlled robot arms (Python bindings).\n\n"
      "SI units everywhere (m, rad, s, N, Nm). Poses, Jacobians, wrenches and stiffnesses are in\n"
      "the base frame (the root link of the chain) unless a frame argument says end_effector.\n"
      "Quaternions are four numbers in the order x, y, z, w. Arrays are NumPy float64 (any real\n"
      "dtype is accepted and converted). Wrong types raise TypeError, wrong shapes ValueError,\n"
      "values the library rejects cartesian_impedance.Error (a ValueError) with its message.";
  m.attr("__version__") = CARTESIAN_IMPEDANCE_VERSION;
  m.attr("MAX_JOINTS") = ci::kMaxJoints;

  py::register_exception<ci::Error>(m, "Error", PyExc_ValueError);
  m.attr("Error").attr("__doc__") =
      "Raised for every input the library rejects; the message names the field, the value and "
      "the valid range. Derives from ValueError. A call that raises changes nothing.";
  // Registered after Error, so that its translator is tried first.
  py::register_exception<ci::QueueFull>(m, "QueueFull", PyExc_RuntimeError);
  m.attr("QueueFull").attr("__doc__") =
      "A valid command that could not be queued because the control loop's inbox was full (is "
      "the loop stepping?). Transient: the same command may succeed later. Derives from "
      "RuntimeError, not from Error.";

  // ---- enumerations ----
  py::enum_<ci::Frame>(m, "Frame", "Frame in which a stiffness or a wrench is given.")
      .value("base", ci::Frame::base, "the root link of the kinematic chain")
      .value("end_effector", ci::Frame::end_effector,
             "the end-effector frame, rotated into the base frame every cycle");
  py::enum_<ci::Status>(m, "Status", "Outcome of one control cycle.")
      .value("ok", ci::Status::ok)
      .value("not_started", ci::Status::not_started)
      .value("invalid_dt", ci::Status::invalid_dt)
      .value("invalid_robot_state", ci::Status::invalid_robot_state)
      .value("numerical_error", ci::Status::numerical_error)
      .value("missing_dynamics", ci::Status::missing_dynamics)
      .value("model_error", ci::Status::model_error);
  py::enum_<ci::TrajectoryState>(m, "TrajectoryState", "Where trajectory execution stands.")
      .value("idle", ci::TrajectoryState::idle)
      .value("executing", ci::TrajectoryState::executing)
      .value("finished", ci::TrajectoryState::finished)
      .value("aborted", ci::TrajectoryState::aborted)
      .value("cancelled", ci::TrajectoryState::cancelled);
  py::enum_<ci::JointType>(m, "JointType")
      .value("revolute", ci::JointType::revolute)
      .value("continuous", ci::JointType::continuous)
      .value("prismatic", ci::JointType::prismatic);

  // ---- Pose ----
  py::class_<ci::Pose>(m, "Pose",
                       "A frame's position [m] and orientation (unit quaternion, x, y, z, w), in "
                       "the base frame. Unpacks as `position, quaternion_xyzw = pose`.")
      .def(py::init([](ArrayLike position, ArrayLike orientation) {
             ci::Pose pose;
             if (!position.is_none()) read_vector(position, "position", Length{3}, pose.position);
             if (!orientation.is_none()) {
               pose.orientation = quaternion_xyzw(orientation, "orientation (x, y, z, w)");
             }
             return pose;
           }),
           py::arg("position") = py::none(), py::arg("orientation") = py::none(),
           "position (3,) [m] (default 0); orientation: quaternion (4,) in the order x, y, z, w "
           "(default identity). Stored as given; the library checks the quaternion's norm "
           "(within 1e-3) where a pose is commanded.")
      .def_static(
          "from_matrix", [](ArrayLike matrix) { return read_pose(matrix, "matrix"); },
          py::arg("matrix"),
          "Pose (quaternion x, y, z, w) from a 4x4 homogeneous transform T_base_frame [m]. "
          "Raises Error if the rotation "
          "part is not a rotation (within 1e-3) or the last row is not [0, 0, 0, 1].")
      .def_property(
          "position", [](const ci::Pose& pose) { return vector_array(pose.position); },
          [](ci::Pose& pose, py::handle value) {
            read_vector(value, "position", Length{3}, pose.position);
          },
          "Position (3,) [m], base frame.")
      .def_property(
          "orientation", [](const ci::Pose& pose) { return xyzw_array(pose.orientation); },
          [](ci::Pose& pose, py::handle value) {
            pose.orientation = quaternion_xyzw(value, "orientation (x, y, z, w)");
          },
          "Orientation as a quaternion (4,) in the order x, y, z, w.")
      .def(
          "matrix", [](const ci::Pose& pose) { return matrix_array(pose_matrix(pose)); },
          "The 4x4 homogeneous transform T_base_frame [m] (the quaternion normalised).")
      .def(
          "rotation_matrix",
          [](const ci::Pose& pose) {
            return matrix_array(pose.orientation.normalized().toRotationMatrix());
          },
          "The 3x3 rotation matrix R_base_frame (the quaternion normalised).")
      .def("__iter__",
           [](const ci::Pose& pose) {
             return py::iter(
                 py::make_tuple(vector_array(pose.position), xyzw_array(pose.orientation)));
           })
      .def("__repr__", &pose_repr)
      .def(py::pickle(
          [](const ci::Pose& pose) {
            return py::make_tuple(vector_array(pose.position), xyzw_array(pose.orientation));
          },
          [](const py::tuple& state) {
            ci::Pose pose;
            read_vector(state[0], "position", Length{3}, pose.position);
            pose.orientation = quaternion_xyzw(state[1], "orientation");
            return pose;
          }));

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

  // ---- states ----
  py::class_<ci::RobotState>(
      m, "RobotState",
      "What the controller reads each cycle: measured joints and the kinematics at them.")
      .def(py::init([](ArrayLike q, ArrayLike dq, PoseLike pose, ArrayLike jacobian, ArrayLike mass,
                       ArrayLike gravity, ArrayLike nullspace_torque) {
             ci::RobotState state;
             read_vector(q, "q", Length{}, state.q);
             read_vector(dq, "dq", Length{}, state.dq);
             state.pose = read_pose(pose, "pose");
             read_matrix(jacobian, "jacobian", Length{6}, Length{}, state.jacobian);
             if (!mass.is_none()) read_matrix(mass, "mass", Length{}, Length{}, state.mass, true);
             if (!gravity.is_none()) read_vector(gravity, "gravity", Length{}, state.gravity);
             if (!nullspace_torque.is_none()) {
               read_vector(nullspace_torque, "nullspace_torque", Length{}, state.nullspace_torque);
             }
             return state;
           }),
           py::arg("q"), py::arg("dq"), py::arg("pose"), py::arg("jacobian"),
           py::arg("mass") = py::none(), py::arg("gravity") = py::none(),
           py::arg("nullspace_torque") = py::none(),
           "q (n,) [rad], dq (n,) [rad/s], pose T_base_ee (Pose, (position, quaternion x, y, z, "
           "w) or 4x4), jacobian (6, n): geometric, rows [linear; angular], reference point the "
           "end-effector origin, base frame. Optional: mass M(q) (n, n) [kg m^2], gravity g(q) "
           "(n,) [Nm], nullspace_torque (n,) [Nm]. 1 <= n <= MAX_JOINTS.")
      .def_property(
          "q", [](const ci::RobotState& s) { return vector_array(s.q); },
          [](ci::RobotState& s, py::handle v) { read_vector(v, "q", Length{}, s.q); },
          "Joint positions (n,) [rad].")
      .def_property(
          "dq", [](const ci::RobotState& s) { return vector_array(s.dq); },
          [](ci::RobotState& s, py::handle v) { read_vector(v, "dq", Length{}, s.dq); },
          "Joint velocities (n,) [rad/s].")
      .def_property(
          "pose", [](const ci::RobotState& s) { return s.pose; },
          [](ci::RobotState& s, py::handle v) { s.pose = read_pose(v, "pose"); },
          "End-effector pose T_base_ee (quaternion x, y, z, w).")
      .def_property(
          "jacobian", [](const ci::RobotState& s) { return matrix_array(s.jacobian); },
          [](ci::RobotState& s, py::handle v) {
            read_matrix(v, "jacobian", Length{6}, Length{}, s.jacobian);
          },
          "Geometric Jacobian (6, n), rows [linear; angular], base frame.")
      .def_property(
          "mass",
          [](const ci::RobotState& s) -> py::object {
            if (s.mass.size() == 0) return py::none();
            return matrix_array(s.mass);
          },
          [](ci::RobotState& s, py::handle v) {
            if (v.is_none()) {
              s.mass.resize(0, 0);
            } else {
              read_matrix(v, "mass", Length{}, Length{}, s.mass, true);
            }
          },
          "Mass matrix M(q) (n, n) [kg m^2], or None.")
      .def_property(
          "gravity", [](const ci::RobotState& s) { return optional_array(s.gravity); },
          [](ci::RobotState& s, py::handle v) {
            if (v.is_none()) {
              s.gravity.resize(0);
            } else {
              read_vector(v, "gravity", Length{}, s.gravity);
            }
          },
          "Gravity torques g(q) (n,) [Nm], or None.")
      .def_property(
          "nullspace_torque",
          [](const ci::RobotState& s) { return optional_array(s.nullspace_torque); },
          [](ci::RobotState& s, py::handle v) {
            if (v.is_none()) {
              s.nullspace_torque.resize(0);
            } else {
              read_vector(v, "nullspace_torque", Length{}, s.nullspace_torque);
            }
          },
          "Extra nullspace torque tau_0 (n,) [Nm], or None.")
      .def("__repr__", [](const ci::RobotState& s) {
        return "RobotState(q=" + numbers_text(s.q) + ", dq=" + numbers_text(s.dq) +
               ", pose=" + pose_repr(s.pose) + ")";
      });
  m.def(
      "make_robot_state",
      [](int num_joints) {
        if (num_joints < 1 || num_joints > ci::kMaxJoints) {
          throw ci::Error("num_joints = " + std::to_string(num_joints) + " is outside [1, " +
                          std::to_string(ci::kMaxJoints) + "]");
        }
        return ci::make_robot_state(num_joints);
      },
      py::arg("num_joints"),
      "A RobotState for num_joints joints, all zero, identity pose (quaternion x, y, z, w = 0, "
      "0, 0, 1), zero Jacobian.");

  py::class_<ci::Targets>(m, "Targets",
                          "Quantities the law is evaluated with (commanded or filtered).")
      .def_property_readonly(
          "pose", [](const ci::Targets& t) { return t.pose; },
          "Reference pose T_base_ref (quaternion x, y, z, w).")
      .def_property_readonly(
          "stiffness", [](const ci::Targets& t) { return matrix_array(t.stiffness); },
          "K (6, 6) in the stiffness frame [N/m, Nm/rad].")
      .def_property_readonly(
          "damping_ratio", [](const ci::Targets& t) { return vector_array(t.damping_ratio); },
          "zeta per axis of the stiffness frame (6,) [-].")
      .def_property_readonly(
          "nullspace_q", [](const ci::Targets& t) { return vector_array(t.nullspace_q); },
          "Nullspace target q_d (n,) [rad].")
      .def_property_readonly(
          "nullspace_stiffness",
          [](const ci::Targets& t) { return vector_array(t.nullspace_stiffness); },
          "K_ns per joint (n,) [Nm/rad].")
      .def_readonly("nullspace_damping_ratio", &ci::Targets::nullspace_damping_ratio,
                    "zeta_ns [-].")
      .def_property_readonly(
          "wrench", [](const ci::Targets& t) { return vector_array(t.wrench); },
          "F = [force; torque] (6,) in the wrench frame [N, Nm].")
      .def_property_readonly(
          "twist", [](const ci::Targets& t) { return vector_array(t.twist); },
          "Reference twist feed-forward (6,) [m/s; rad/s], base frame.")
      .def_property_readonly(
          "nullspace_dq", [](const ci::Targets& t) { return vector_array(t.nullspace_dq); },
          "Nullspace target velocity (n,) [rad/s].");

  py::class_<ci::ActiveLimits>(m, "ActiveLimits", "Which limits shaped the last command.")
      .def_readonly("stiffness_saturated", &ci::ActiveLimits::stiffness_saturated)
      .def_readonly("damping_ratio_saturated", &ci::ActiveLimits::damping_ratio_saturated)
      .def_readonly("nullspace_stiffness_saturated",
                    &ci::ActiveLimits::nullspace_stiffness_saturated)
      .def_readonly("wrench_saturated", &ci::ActiveLimits::wrench_saturated)
      .def_readonly("translation_error_clipped", &ci::ActiveLimits::translation_error_clipped)
      .def_readonly("rotation_error_clipped", &ci::ActiveLimits::rotation_error_clipped)
      .def_readonly("joint_torque_saturated", &ci::ActiveLimits::joint_torque_saturated)
      .def_readonly("torque_rate_limited", &ci::ActiveLimits::torque_rate_limited)
      .def_readonly("joint_torque_limit_ramping", &ci::ActiveLimits::joint_torque_limit_ramping)
      .def("__repr__", [](const ci::ActiveLimits& l) {
        std::string active;
        const std::pair<const char*, bool> flags[] = {
            {"stiffness_saturated", l.stiffness_saturated},
            {"damping_ratio_saturated", l.damping_ratio_saturated},
            {"nullspace_stiffness_saturated", l.nullspace_stiffness_saturated},
            {"wrench_saturated", l.wrench_saturated},
            {"translation_error_clipped", l.translation_error_clipped},
            {"rotation_error_clipped", l.rotation_error_clipped},
            {"joint_torque_saturated", l.joint_torque_saturated},
            {"torque_rate_limited", l.torque_rate_limited},
            {"joint_torque_limit_ramping", l.joint_torque_limit_ramping}};
        for (const auto& [name, on] : flags) {
          if (on) active += (active.empty() ? "" : ", ") + std::string(name);
        }
        return "ActiveLimits(" + (active.empty() ? std::string("none") : active) + ")";
      });

  py::class_<ci::Fault>(m, "Fault", "Which input made a cycle fail closed.")
      .def_property_readonly(
          "input", [](const ci::Fault& f) { return std::string(f.input); },
          "'dt', 'q', 'dq', 'pose', 'jacobian', 'mass', 'gravity', ... ('' if none)")
      .def_readonly("index", &ci::Fault::index, "element (joint) index, or -1")
      .def_readonly("value", &ci::Fault::value, "the offending value (the size, for a wrong size)")
      .def_property_readonly(
          "reason", [](const ci::Fault& f) { return std::string(f.reason); },
          "'is not finite', 'has the wrong size', 'is above plausibility.dt.max', ...")
      .def_property_readonly(
          "bound", [](const ci::Fault& f) { return f.has_bound ? py::cast(f.bound) : py::none(); },
          "the bound it broke, or None")
      .def("__str__", [](const ci::Fault& f) { return ci::to_string(f); })
      .def("__bool__", [](const ci::Fault& f) { return f.input[0] != '\0'; })
      .def("__repr__", [](const ci::Fault& f) { return "Fault('" + ci::to_string(f) + "')"; });

  py::class_<ci::ControllerState>(m, "ControllerState", "Snapshot written by every update().")
      .def_readonly("status", &ci::ControllerState::status)
      .def_readonly("fault", &ci::ControllerState::fault,
                    "Why the last cycle failed closed (falsy when status is ok).")
      .def_property_readonly(
          "joint_torque_limit",
          [](const ci::ControllerState& s) { return vector_array(s.joint_torque_limit); },
          "Torque bound in force per joint (n,) [Nm]: limits.joint_torque, or above it while "
          "ramping down to a lowered limit.")
      .def_property_readonly(
          "pose", [](const ci::ControllerState& s) { return s.pose; },
          "Measured end-effector pose T_base_ee (quaternion x, y, z, w).")
      .def_property_readonly(
          "pose_error", [](const ci::ControllerState& s) { return vector_array(s.pose_error); },
          "e = [p - p_d; log(R R_d^T)] (6,) [m; rad], base frame, after clipping.")
      .def_readonly("commanded", &ci::ControllerState::commanded,
                    "Targets as last commanded (after validation and saturation).")
      .def_readonly("filtered", &ci::ControllerState::filtered, "Targets the law used.")
      .def_readonly("stiffness_frame", &ci::ControllerState::stiffness_frame)
      .def_readonly("wrench_frame", &ci::ControllerState::wrench_frame)
      .def_property_readonly(
          "wrench_base", [](const ci::ControllerState& s) { return vector_array(s.wrench_base); },
          "Filtered F (6,) in the base frame [N; Nm].")
      .def_property_readonly(
          "tau_cartesian",
          [](const ci::ControllerState& s) { return vector_array(s.tau_cartesian); },
          "J^T (-K e - D J dq) (n,) [Nm].")
      .def_property_readonly(
          "tau_nullspace",
          [](const ci::ControllerState& s) { return vector_array(s.tau_nullspace); },
          "N tau_0 (n,) [Nm].")
      .def_property_readonly(
          "tau_wrench", [](const ci::ControllerState& s) { return vector_array(s.tau_wrench); },
          "J^T F (n,) [Nm].")
      .def_property_readonly(
          "tau_gravity", [](const ci::ControllerState& s) { return vector_array(s.tau_gravity); },
          "g(q) if dynamics.gravity_compensation, else 0 (n,) [Nm].")
      .def_property_readonly(
          "tau", [](const ci::ControllerState& s) { return vector_array(s.tau); },
          "Commanded torque after the torque and rate limits (n,) [Nm].")
      .def_readonly("limits", &ci::ControllerState::limits)
      .def(
          "stiffness_base",
          [](const ci::ControllerState& s) { return matrix_array(s.stiffness_base()); },
          "Filtered K (6, 6) in the base frame [N/m, Nm/rad].")
      .def(
          "damping_base",
          [](const ci::ControllerState& s) { return matrix_array(s.damping_base()); },
          "D the law used (6, 6) in the base frame [N s/m, Nm s/rad].")
      .def("__repr__", [](const ci::ControllerState& s) {
        return std::string("ControllerState(status=") + ci::to_string(s.status) +
               (s.fault.input[0] != '\0' ? ", fault='" + ci::to_string(s.fault) + "'" : "") +
               ", tau=" + numbers_text(s.tau) + ")";
      });

  py::class_<ci::TrajectoryProgress>(m, "TrajectoryProgress")
      .def_readonly("state", &ci::TrajectoryProgress::state)
      .def_readonly("id", &ci::TrajectoryProgress::id,
                    "id returned by execute_trajectory() of the one reported")
      .def_readonly("time", &ci::TrajectoryProgress::time, "[s] since it started")
      .def_readonly("duration", &ci::TrajectoryProgress::duration, "[s] of its last point")
      .def_readonly("goal_error", &ci::TrajectoryProgress::goal_error,
                    "[rad] largest |q - q_goal| (once past the end)")
      .def("__repr__", [](const ci::TrajectoryProgress& p) {
        return "TrajectoryProgress(" + trajectory_text(p) +
               ", goal_error=" + ci::format_number(p.goal_error) + ")";
      });

  py::class_<ci::LoopState>(m, "LoopState", "What one ControlLoop step publishes.")
      .def_readonly("controller", &ci::LoopState::controller,
                    "The law's snapshot: errors, targets, torque parts, limits.")
      .def_property_readonly(
          "q", [](const ci::LoopState& s) { return vector_array(s.q); },
          "Measured joint positions (n,) [rad].")
      .def_property_readonly(
          "dq", [](const ci::LoopState& s) { return vector_array(s.dq); },
          "Measured joint velocities (n,) [rad/s].")
      .def_readonly("trajectory", &ci::LoopState::trajectory)
      .def_readonly("cycle", &ci::LoopState::cycle, "steps since start()")
      .def_readonly("time", &ci::LoopState::time, "[s] sum of dt since start()")
      .def_readonly("commands_applied", &ci::LoopState::commands_applied)
      .def("__repr__", [](const ci::LoopState& s) {
        return "LoopState(cycle=" + std::to_string(s.cycle) +
               ", time=" + ci::format_number(s.time) +
               " s, status=" + ci::to_string(s.controller.status) +
               ", trajectory=" + trajectory_text(s.trajectory) + ")";
      });

  // ---- controller ----
  using Controller = ci::CartesianImpedanceController;
  py::class_<Controller> controller(
      m, "CartesianImpedanceController",
      "The control law on its own: tau = J^T(-K e - D J dq) + N tau_0 + J^T F, with filters and "
      "limits. You provide the RobotState (kinematics) each cycle; ControlLoop does that from a "
      "RobotModel. Setters validate and raise Error (a rejected command changes nothing).");
  def_commands<Controller, Controller>(
      controller, [](Controller& self) -> Controller& { return self; }, "Sets");
  controller
      .def(py::init([](int num_joints, ParametersLike parameters) {
             return std::make_unique<Controller>(num_joints, read_parameters(parameters));
           }),
           py::arg("num_joints"), py::arg("parameters") = py::none(),
           "num_joints in [1, MAX_JOINTS]; parameters: Parameters, dict or None (defaults).")
      .def_property_readonly("num_joints", &Controller::num_joints)
      .def_property_readonly(
          "parameters", [](const Controller& c) { return c.parameters(); },
          "A copy of the configuration in force.")
      .def(
          "set_parameters",
          [](Controller& c, ParametersLike parameters) {
            c.set_parameters(read_parameters(parameters));
          },
          py::arg("parameters"), "Replaces the whole configuration (Parameters or dict).")
      .def(
          "start",
          [](Controller& c, const ci::RobotState& robot, ArrayLike tau_previous) {
            if (tau_previous.is_none()) return c.start(robot);
            ci::JointVector tau;
            read_vector(tau_previous, "tau_previous", Length{c.num_joints()}, tau);
            c.start(robot, tau);
          },
          py::arg("robot"), py::arg("tau_previous") = py::none(),
          "Starts from the measured state: reference pose = current pose, nullspace target = q. "
          "tau_previous (n,) [Nm]: the torque the robot receives now (default zero).")
      .def_property_readonly("started", &Controller::started)
      .def(
          "update",
          [](Controller& c, const ci::RobotState& robot, Real dt) {
            return c.update(robot, read_scalar(dt, "dt"));
          },
          py::arg("robot"), py::arg("dt"),
          "One control cycle with the elapsed dt [s]. Never raises for bad values: returns a "
          "Status and ramps the torque toward zero instead.")
      .def_property_readonly(
          "torque", [](const Controller& c) { return vector_array(c.torque()); },
          "Commanded joint torque of the last update() (n,) [Nm].")
      .def_property_readonly(
          "state", [](const Controller& c) { return c.state(); },
          "A copy of the snapshot of the last update() (ControllerState).");

  // ---- robot model ----
  py::class_<ci::JointLimits>(m, "JointLimits", "Joint limits from the URDF, base to tip.")
      .def_property_readonly(
          "position_lower", [](const ci::JointLimits& l) { return vector_array(l.position_lower); },
          "[rad or m]; -inf for continuous joints")
      .def_property_readonly(
          "position_upper", [](const ci::JointLimits& l) { return vector_array(l.position_upper); },
          "[rad or m]; +inf for continuous joints")
      .def_property_readonly(
          "velocity", [](const ci::JointLimits& l) { return vector_array(l.velocity); },
          "[rad/s or m/s]; +inf where the URDF gives none")
      .def_property_readonly(
          "effort", [](const ci::JointLimits& l) { return vector_array(l.effort); },
          "[Nm or N]; +inf where the URDF gives none");

  py::class_<ci::Kinematics>(m, "Kinematics", "What RobotModel.compute() returns.")
      .def_property_readonly(
          "pose", [](const ci::Kinematics& k) { return k.pose; },
          "T_base_ee (quaternion x, y, z, w): tip link times the tool offset, base frame.")
      .def_property_readonly(
          "jacobian", [](const ci::Kinematics& k) { return matrix_array(k.jacobian); },
          "Geometric Jacobian (6, n), rows [linear; angular], reference point the end-effector "
          "origin, base frame.")
      .def_property_readonly(
          "mass",
          [](const ci::Kinematics& k) -> py::object {
            if (!k.has_dynamics) return py::none();
            return matrix_array(k.mass);
          },
          "M(q) (n, n) [kg m^2], or None without dynamics.")
      .def_property_readonly(
          "gravity",
          [](const ci::Kinematics& k) -> py::object {
            if (!k.has_dynamics) return py::none();
            return vector_array(k.gravity);
          },
          "g(q) (n,) [Nm]: torques that hold the arm against gravity, or None without dynamics.")
      .def_property_readonly(
          "coriolis",
          [](const ci::Kinematics& k) -> py::object {
            if (!k.has_dynamics) return py::none();
            return vector_array(k.coriolis);
          },
          "C(q, dq) dq (n,) [Nm], or None without dynamics.")
      .def_readonly("has_dynamics", &ci::Kinematics::has_dynamics)
      .def("__repr__", [](const ci::Kinematics& k) {
        return "Kinematics(pose=" + pose_repr(k.pose) +
               (k.has_dynamics ? ", with dynamics)" : ", kinematics only)");
      });

  py::class_<Model>(
      m, "RobotModel",
      "The chain base_link -> tip_link of a URDF (urdfdom + KDL), plus a fixed tool offset. "
      "Poses, Jacobians and gravity torques are in the base frame (the frame of base_link).")
      .def_static(
          "from_urdf_file",
          [](PathLike path, const std::string& base_link, const std::string& tip_link,
             PoseLike tool, ArrayLike gravity) {
            return load_model(true, read_path(path, "path"), base_link, tip_link, tool, gravity);
          },
          py::arg("path"), py::arg("base_link"), py::arg("tip_link"), py::arg("tool") = py::none(),
          py::arg("gravity") = py::none(),
          "Loads a URDF file. tool: T_tip_tool, the end-effector frame in the tip-link frame "
          "(Pose, (position [m], quaternion x, y, z, w) or 4x4; default identity). gravity: "
          "acceleration (3,) [m/s^2] in the base frame (default (0, 0, -9.81)). Raises Error "
          "naming the path for a missing file, unknown links, an unsupported chain, ...")
      .def_static(
          "from_urdf_string",
          [](const std::string& xml, const std::string& base_link, const std::string& tip_link,
             PoseLike tool, ArrayLike gravity) {
            return load_model(false, xml, base_link, tip_link, tool, gravity);
          },
          py::arg("xml"), py::arg("base_link"), py::arg("tip_link"), py::arg("tool") = py::none(),
          py::arg("gravity") = py::none(), "As from_urdf_file(), from URDF text.")
      .def_property_readonly("num_joints", [](const Model& s) { return s.model.num_joints(); })
      .def_property_readonly(
          "joint_names", [](const Model& s) { return s.model.joint_names(); },
          "Movable joints, base to tip: the order of every joint vector.")
      .def_property_readonly("joint_types", [](const Model& s) { return s.model.joint_types(); })
      .def_property_readonly("limits", [](const Model& s) { return s.model.limits(); })
      .def_property_readonly("robot_name", [](const Model& s) { return s.model.robot_name(); })
      .def_property_readonly("base_link", [](const Model& s) { return s.model.base_link(); })
      .def_property_readonly("tip_link", [](const Model& s) { return s.model.tip_link(); })
      .def_property_readonly(
          "tool",
          [](const Model& s) {
            const Eigen::Isometry3d& tool = s.model.tool();
            return ci::Pose{tool.translation(), Eigen::Quaterniond(tool.rotation())};
          },
          "T_tip_tool (quaternion x, y, z, w).")
      .def_property_readonly(
          "gravity", [](const Model& s) { return vector_array(s.model.gravity_base()); },
          "Gravitational acceleration (3,) [m/s^2], base frame.")
      .def_property_readonly(
          "moving_mass", [](const Model& s) { return s.model.moving_mass(); },
          "Mass the dynamics include [kg].")
      .def(
          "compute",
          [](Model& s, ArrayLike q, ArrayLike dq, bool dynamics) {
            const int n = s.model.num_joints();
            const ci::JointVector joints = finite_joints(q, "q", n);
            const ci::JointVector velocities =
                dq.is_none() ? ci::JointVector::Zero(n) : finite_joints(dq, "dq", n);
            ci::Kinematics kinematics = s.workspace.make_kinematics();
            if (!s.workspace.compute(joints, velocities, kinematics, dynamics)) {
              throw ci::Error("RobotModel.compute: the result at q = " + numbers_text(joints) +
                              " is not finite");
            }
            return kinematics;
          },
          py::arg("q"), py::arg("dq") = py::none(), py::arg("dynamics") = true,
          "Kinematics at q (n,) [rad] and dq (n,) [rad/s] (default zero): pose T_base_ee "
          "(quaternion x, y, z, w), "
          "Jacobian (6, n) and, if dynamics, mass M(q), gravity g(q) and coriolis C(q, dq) dq. "
          "Raises Error for non-finite q or dq.")
      .def(
          "compute_pose",
          [](Model& s, ArrayLike q) {
            const ci::JointVector joints = finite_joints(q, "q", s.model.num_joints());
            ci::Pose pose;
            if (!s.workspace.compute_pose(joints, pose)) {
              throw ci::Error("RobotModel.compute_pose: the result is not finite");
            }
            return pose;
          },
          py::arg("q"), "Forward kinematics T_base_ee at q (n,) [rad] (quaternion x, y, z, w).")
      .def("__repr__", [](const Model& s) {
        return "RobotModel('" + s.model.robot_name() + "', " + s.model.base_link() + " -> " +
               s.model.tip_link() + ", " + std::to_string(s.model.num_joints()) + " joints)";
      });

  // ---- control loop ----
  const ci::LoopCapacity default_capacity;
  py::class_<Loop> control_loop(
      m, "ControlLoop",
      "A robot model, the controller and a trajectory executor behind step(q, dq, dt) -> tau.\n\n"
      "One thread runs start()/step(); any thread may send commands (the set_* methods, "
      "execute_trajectory, cancel_trajectory) and read latest_state(). Commands are validated "
      "when sent (Error on bad input) and applied at the next step.");
  def_commands<Loop, ci::ControlLoop>(
      control_loop, [](Loop& self) -> ci::ControlLoop& { return self.loop; }, "Queues");
  control_loop
      .def(py::init([](py::object model, ParametersLike parameters, int commands, int points) {
             if (!py::isinstance<Model>(model)) {
               throw py::type_error("model must be a RobotModel, got " + type_name(model));
             }
             return std::make_unique<Loop>(std::move(model), read_parameters(parameters),
                                           ci::LoopCapacity{commands, points});
           }),
           py::arg("model"), py::arg("parameters") = py::none(),
           py::arg("command_capacity") = default_capacity.commands,
           py::arg("max_trajectory_points") = default_capacity.trajectory_points,
           "model: RobotModel; parameters: Parameters, dict or None (defaults). Raises Error if "
           "the parameters are invalid for the model's joint count.")
      .def_property_readonly(
          "model", [](const Loop& self) { return self.model_object; }, "The RobotModel.")
      .def_property_readonly("num_joints", [](const Loop& self) { return self.loop.num_joints(); })
      .def_property_readonly(
          "started", [](Loop& self) { return self.cycle().started(); },
          "True once start() has been called.")
      .def(
          "start",
          [](Loop& self, ArrayLike q, ArrayLike dq, ArrayLike tau_previous) {
            ci::ControlLoop& loop = self.cycle();
            const int n = loop.num_joints();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{n}, joints);
            read_vector(dq, "dq", Length{n}, velocities);
            if (tau_previous.is_none()) return loop.start(joints, velocities);
            ci::JointVector tau;
            read_vector(tau_previous, "tau_previous", Length{n}, tau);
            loop.start(joints, velocities, tau);
          },
          py::arg("q"), py::arg("dq"), py::arg("tau_previous") = py::none(),
          "Starts (or restarts) from the measured q (n,) [rad] and dq (n,) [rad/s]: reference "
          "pose = current pose, nullspace target = q. tau_previous (n,) [Nm]: the torque the "
          "robot receives now (default g(q) with dynamics.gravity_compensation, else zero). "
          "Raises Error for non-finite values.")
      .def(
          "step",
          [](Loop& self, ArrayLike q, ArrayLike dq, Real dt) {
            ci::ControlLoop& loop = self.cycle();
            const int n = loop.num_joints();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{n}, joints);
            read_vector(dq, "dq", Length{n}, velocities);
            return vector_array(loop.step(joints, velocities, read_scalar(dt, "dt")));
          },
          py::arg("q"), py::arg("dq"), py::arg("dt"),
          "One control cycle: q (n,) [rad], dq (n,) [rad/s], dt [s] since the last step. Returns "
          "the joint torque to command (n,) [Nm] (a new array). Wrong shapes or types raise; "
          "non-finite values do not: like the C++ cycle it then reports a Status "
          "(state.controller.status) and ramps the torque toward zero within the rate limit.")
      .def_property_readonly(
          "state", [](Loop& self) { return self.cycle().state(); },
          "A copy of the state after the last step (LoopState; cycle thread).")
      .def_property_readonly(
          "torque", [](Loop& self) { return vector_array(self.cycle().state().controller.tau); },
          "Torque of the last step (n,) [Nm].")
      .def(
          "latest_state", [](const Loop& self) { return self.loop.latest_state(); },
          "A copy of the newest published LoopState (any thread).")
      .def(
          "latest_parameters", [](const Loop& self) { return self.loop.latest_parameters(); },
          "Parameters in force as of the last step (any thread).")
      .def(
          "set_parameters",
          [](Loop& self, ParametersLike parameters) {
            self.loop.set_parameters(read_parameters(parameters));
          },
          py::arg("parameters"), "Queues a whole new configuration (Parameters or dict).")
      .def(
          "start_teaching",
          [](Loop& self, bool keep_nullspace) { self.loop.start_teaching(keep_nullspace); },
          py::arg("keep_nullspace") = false,
          "Kinesthetic teaching: zero Cartesian stiffness (and nullspace stiffness unless "
          "keep_nullspace). Any later stiffness command ends it.")
      .def(
          "execute_trajectory",
          [](Loop& self, ArrayLike times, ArrayLike positions, ArrayLike velocities,
             std::optional<std::vector<std::string>> joint_names) {
            ci::JointTrajectory trajectory;
            trajectory.joint_names = joint_names ? *joint_names : self.loop.model().joint_names();
            const Length columns{static_cast<Eigen::Index>(trajectory.joint_names.size()),
                                 ci::kMaxJoints};
            Eigen::VectorXd time_values;
            read_vector(times, "times", Length{-1, kUnbounded}, time_values);
            trajectory.times.assign(time_values.data(), time_values.data() + time_values.size());
            const auto rows = [&](py::handle object, const char* name) {
              Eigen::MatrixXd matrix;
              read_matrix(object, name, Length{-1, kUnbounded}, columns, matrix, false, "points");
              std::vector<std::vector<double>> points(static_cast<std::size_t>(matrix.rows()));
              for (Eigen::Index i = 0; i < matrix.rows(); ++i) {
                points[static_cast<std::size_t>(i)].resize(static_cast<std::size_t>(matrix.cols()));
                for (Eigen::Index j = 0; j < matrix.cols(); ++j) {
                  points[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] = matrix(i, j);
                }
              }
              return points;
            };
            trajectory.positions = rows(positions, "positions");
            if (!velocities.is_none()) trajectory.velocities = rows(velocities, "velocities");
            return self.loop.execute_trajectory(trajectory);
          },
          py::arg("times"), py::arg("positions"), py::arg("velocities") = py::none(),
          py::arg("joint_names") = py::none(),
          "Queues a joint trajectory and returns its id. times (m,) [s] from the start, strictly "
          "increasing (a point at 0 is taken as the start state); positions (m, k) [rad]; "
          "velocities (m, k) [rad/s] or None (smooth, shape-preserving); joint_names: k names in "
          "any order (default: the model's joint names). It starts at the next step from where "
          "the arm is (or from where a running trajectory is, which it preempts). Raises Error "
          "for unknown joints, times not increasing, positions outside the URDF limits, ...")
      .def(
          "cancel_trajectory", [](Loop& self) { self.loop.cancel_trajectory(); },
          "Stops a running trajectory; the arm holds where it is.")
      .def(
          "_benchmark_steps",
          [](Loop& self, ArrayLike q, ArrayLike dq, double dt, std::int64_t count) {
            ci::ControlLoop& loop = self.cycle();
            const int n = loop.num_joints();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{n}, joints);
            read_vector(dq, "dq", Length{n}, velocities);
            Claim claim(self.running, "this ControlLoop");
            double sink = 0.0, cpu = 0.0;
            std::chrono::duration<double> elapsed{};
            {
              py::gil_scoped_release release;
              const auto begin = std::chrono::steady_clock::now();
              const std::clock_t cpu_begin = std::clock();
              for (std::int64_t k = 0; k < count; ++k) {
                sink += loop.step(joints, velocities, dt)[0];
              }
              cpu = static_cast<double>(std::clock() - cpu_begin) / CLOCKS_PER_SEC;
              elapsed = std::chrono::steady_clock::now() - begin;
            }
            return py::make_tuple(elapsed.count(), cpu, sink);  // with the GIL again
          },
          py::arg("q"), py::arg("dq"), py::arg("dt"), py::arg("count"),
          "Internal (python/benchmarks): `count` steps in C++ with the same q, dq, dt; returns "
          "(wall seconds, CPU seconds, checksum).")
      .def("__repr__", [](const Loop& self) {
        const ci::RobotModel& model = self.loop.model();
        std::string text = "ControlLoop(robot='" + model.robot_name() + "', " +
                           std::to_string(model.num_joints()) + " joints, ";
        if (self.running.load()) return text + "running in Simulation.run())";
        const ci::LoopState& state = self.loop.state();
        if (!self.loop.started()) {
          text += "not started";
        } else {
          text += "started, cycle " + std::to_string(state.cycle) +
                  ", t = " + ci::format_number(state.time) + " s, status " +
                  ci::to_string(state.controller.status);
        }
        return text + ", trajectory " + trajectory_text(state.trajectory) + ")";
      });

#ifdef CARTESIAN_IMPEDANCE_PYTHON_SIM
  // ---- simulation ----
  py::module_ sim = m.def_submodule(
      "sim",
      "MuJoCo simulation of a torque-controlled arm: joint torques in, joint state out, gravity "
      "compensated like Panda and iiwa firmware (on by default), pushes, static boxes, contact "
      "wrenches, offscreen rendering. Poses and wrenches are in MuJoCo's world frame, which is "
      "the controller's base frame for the project's robot files; wrenches are [force; torque].");
  // `import cartesian_impedance.sim` works too.
  py::module_::import("sys").attr("modules")["cartesian_impedance.sim"] = sim;

  const ci::sim::SimulationOptions default_options;
  const auto option_args = [&default_options]() {
    return std::make_tuple(py::arg("timestep") = default_options.timestep,
                           py::arg("gravity_compensation") = default_options.gravity_compensation,
                           py::arg("keyframe") = default_options.keyframe,
                           py::arg("joint_names") = py::none(),
                           py::arg("multi_point_contacts") = default_options.multi_point_contacts);
  };
  const char* options_doc =
      " Options: timestep [s] (replaces the model's); gravity_compensation: each joint receives "
      "tau + g(q), as robot firmware does; keyframe to reset to ('' or missing: the model's "
      "default qpos); joint_names: order of q, dq and tau (default: the model's hinge and slide "
      "joints); multi_point_contacts: steadier face-on-face contact forces.";

  py::class_<ci::sim::Box>(sim, "Box",
                           "A static box (table, wall, step) that collides with the robot.")
      .def(py::init([](ArrayLike center, ArrayLike half_size, ArrayLike orientation,
                       const std::string& name) {
             ci::sim::Box box;
             box.name = name;
             read_vector(center, "center", Length{3}, box.center);
             read_vector(half_size, "half_size", Length{3}, box.half_size);
             if (!orientation.is_none()) {
               box.orientation = quaternion_xyzw(orientation, "orientation (x, y, z, w)");
             }
             return box;
           }),
           py::arg("center"), py::arg("half_size"), py::arg("orientation") = py::none(),
           py::arg("name") = "",
           "center (3,) [m] in the world frame, half_size (3,) [m] along the box axes, "
           "orientation: quaternion (4,) x, y, z, w of the box axes (default identity); name: "
           "geom name ('' = scene_box_<index>).")
      .def_static(
          "table",
          [](ArrayLike center_xy, ArrayLike half_size_xy, Real top_z, const std::string& name) {
            Eigen::Vector2d center, half;
            read_vector(center_xy, "center_xy", Length{2}, center);
            read_vector(half_size_xy, "half_size_xy", Length{2}, half);
            return ci::sim::Box::table(center, half, read_scalar(top_z, "top_z"), name);
          },
          py::arg("center_xy"), py::arg("half_size_xy"), py::arg("top_z"), py::arg("name") = "",
          "A table on the floor whose top is at top_z [m], centred at center_xy (2,) [m], half "
          "extents half_size_xy (2,) [m].")
      .def_readwrite("name", &ci::sim::Box::name)
      .def_property(
          "center", [](const ci::sim::Box& b) { return vector_array(b.center); },
          [](ci::sim::Box& b, py::handle v) { read_vector(v, "center", Length{3}, b.center); },
          "(3,) [m], world frame")
      .def_property(
          "half_size", [](const ci::sim::Box& b) { return vector_array(b.half_size); },
          [](ci::sim::Box& b, py::handle v) {
            read_vector(v, "half_size", Length{3}, b.half_size);
          },
          "(3,) [m]")
      .def_property(
          "orientation", [](const ci::sim::Box& b) { return xyzw_array(b.orientation); },
          [](ci::sim::Box& b, py::handle v) {
            b.orientation = quaternion_xyzw(v, "orientation (x, y, z, w)");
          },
          "quaternion (4,) in the order x, y, z, w")
      .def("__repr__", [](const ci::sim::Box& b) {
        return "Box(name='" + b.name + "', center=" + numbers_text(b.center) +
               ", half_size=" + numbers_text(b.half_size) +
               ", orientation_xyzw=" + numbers_text(b.orientation.coeffs()) + ")";
      });

  py::class_<Sim> simulation(
      sim, "Simulation",
      "A simulated robot (MuJoCo). Not thread-safe: one thread drives it. Loaders and setters "
      "raise Error on bad input.");
  std::apply(
      [&](auto... args) {
        simulation.def_static(
            "from_mjcf_file",
            [](PathLike path, Real timestep, bool gravity_compensation, const std::string& keyframe,
               std::optional<std::vector<std::string>> names, bool multi_point_contacts) {
              return std::make_unique<Sim>(ci::sim::Simulation::from_mjcf_file(
                  read_path(path, "path"),
                  simulation_options(timestep, gravity_compensation, keyframe, names,
                                     multi_point_contacts)));
            },
            py::arg("path"), args...,
            (std::string("Loads an MJCF file (e.g. models/panda/panda.xml); each joint is "
                         "driven by its <motor>, or through qfrc_applied without one.") +
             options_doc)
                .c_str());
        simulation.def_static(
            "from_urdf_file",
            [](PathLike path, Real timestep, bool gravity_compensation, const std::string& keyframe,
               std::optional<std::vector<std::string>> names, bool multi_point_contacts) {
              return std::make_unique<Sim>(ci::sim::Simulation::from_urdf_file(
                  read_path(path, "path"),
                  simulation_options(timestep, gravity_compensation, keyframe, names,
                                     multi_point_contacts)));
            },
            py::arg("path"), args...,
            (std::string("Loads a URDF with MuJoCo's importer (no actuators, no floor, no "
                         "keyframe).") +
             options_doc)
                .c_str());
        sim.def(
            "make_scene",
            [](PathLike path, const std::vector<ci::sim::Box>& boxes, Real timestep,
               bool gravity_compensation, const std::string& keyframe,
               std::optional<std::vector<std::string>> names, bool multi_point_contacts) {
              return std::make_unique<Sim>(
                  ci::sim::make_scene(read_path(path, "robot_mjcf"), boxes,
                                      simulation_options(timestep, gravity_compensation, keyframe,
                                                         names, multi_point_contacts)));
            },
            py::arg("robot_mjcf"), py::arg("boxes"), args...,
            (std::string("Loads the MJCF robot file with the boxes (a list of Box) added to its "
                         "world, writing no file.") +
             options_doc)
                .c_str());
      },
      option_args());

  simulation.def_property_readonly("num_joints", [](Sim& s) { return s.get().num_joints(); })
      .def_property_readonly(
          "joint_names", [](Sim& s) { return s.get().joint_names(); },
          "Joint names in the order q, dq and tau are exchanged.")
      .def_property_readonly(
          "time", [](Sim& s) { return s.get().time(); }, "Simulated time [s].")
      .def_property_readonly(
          "timestep", [](Sim& s) { return s.get().timestep(); }, "Integration step [s].")
      .def_property_readonly(
          "q", [](Sim& s) { return vector_array(s.get().q()); }, "Joint positions (n,) [rad].")
      .def_property_readonly(
          "dq", [](Sim& s) { return vector_array(s.get().dq()); }, "Joint velocities (n,) [rad/s].")
      .def_property_readonly(
          "torque", [](Sim& s) { return vector_array(s.get().torque()); },
          "Applied commanded torque after clipping (n,) [Nm], without gravity compensation.")
      .def_property_readonly(
          "torque_lower_limits", [](Sim& s) { return vector_array(s.get().torque_lower_limits()); },
          "(n,) [Nm]; -inf without a limited actuator")
      .def_property_readonly(
          "torque_upper_limits", [](Sim& s) { return vector_array(s.get().torque_upper_limits()); },
          "(n,) [Nm]; +inf without a limited actuator")
      .def_property_readonly(
          "armature", [](Sim& s) { return vector_array(s.get().armature()); },
          "Rotor inertia per joint (n,) [kg m^2]: the value for the parameter dynamics.armature.")
      .def_property_readonly(
          "friction_loss", [](Sim& s) { return vector_array(s.get().friction_loss()); },
          "Coulomb friction per joint (n,) [Nm]")
      .def_property_readonly("model_name", [](Sim& s) { return s.get().model_name(); })
      .def(
          "set_state",
          [](Sim& s, ArrayLike q, ArrayLike dq) {
            ci::sim::Simulation& simulation = s.get();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{simulation.num_joints()}, joints);
            read_vector(dq, "dq", Length{simulation.num_joints()}, velocities);
            simulation.set_state(joints, velocities);
          },
          py::arg("q"), py::arg("dq"),
          "Sets joint positions (n,) [rad] and velocities (n,) [rad/s]; time is kept.")
      .def(
          "reset", [](Sim& s) { s.get().reset(); },
          "Back to the keyframe at time 0: zero torque, no pushes.")
      .def(
          "set_torque",
          [](Sim& s, ArrayLike tau) {
            ci::sim::Simulation& simulation = s.get();
            ci::JointVector values;
            read_vector(tau, "tau", Length{simulation.num_joints()}, values);
            return simulation.set_torque(values);
          },
          py::arg("tau"),
          "Commands joint torques (n,) [Nm] from the next step on (gravity compensation comes on "
          "top), clipped to the actuator ranges. Returns True if any value was clipped.")
      .def(
          "step",
          [](Sim& s, std::int64_t count) {
            ci::sim::Simulation& simulation = s.get();
            if (count < 0) throw ci::Error("count = " + std::to_string(count) + " must be >= 0");
            if (count == 1) return simulation.step();
            Claim claim(s.running, "this Simulation");
            py::gil_scoped_release release;
            for (std::int64_t k = 0; k < count; ++k) simulation.step();
          },
          py::arg("count") = 1,
          "Advances by `count` timesteps at the commanded torque (releases the GIL).")
      .def(
          "run",
          [](Sim& self, Loop& control, Real seconds_object, bool until_trajectory_done) {
            ci::sim::Simulation& simulation = self.get();
            ci::ControlLoop& loop = control.cycle();
            const double seconds = read_scalar(seconds_object, "seconds");
            if (!(seconds >= 0.0) || !std::isfinite(seconds)) {
              throw ci::Error("seconds = " + ci::format_number(seconds) +
                              " must be finite and >= 0");
            }
            if (simulation.joint_names() != loop.model().joint_names()) {
              throw ci::Error("the simulation exchanges joints " +
                              std::string(py::str(py::cast(simulation.joint_names()))) +
                              " but the control loop's model has " +
                              std::string(py::str(py::cast(loop.model().joint_names()))) +
                              ": load the simulation with joint_names=loop.model.joint_names");
            }
            if (!loop.started()) {
              throw std::runtime_error(
                  "the control loop has not been started: call loop.start(sim.q, sim.dq) first");
            }
            const std::int64_t steps = std::llround(seconds / simulation.timestep());
            const double dt = simulation.timestep();
            Claim simulation_claim(self.running, "this Simulation");
            Claim loop_claim(control.running, "this ControlLoop");
            std::int64_t done = 0;
            py::gil_scoped_release release;
            while (done < steps) {
              simulation.set_torque(loop.step(simulation.q(), simulation.dq(), dt));
              simulation.step();
              ++done;
              if (until_trajectory_done) {
                const ci::TrajectoryState state = loop.state().trajectory.state;
                if (state != ci::TrajectoryState::executing && state != ci::TrajectoryState::idle) {
                  break;
                }
              }
              if (done % kSignalCheckSteps == 0) {
                py::gil_scoped_acquire acquire;
                if (PyErr_CheckSignals() != 0) throw py::error_already_set();
              }
            }
            return done;
          },
          py::arg("loop"), py::arg("seconds"), py::arg("until_trajectory_done") = false,
          "Closed loop for `seconds` of simulated time, in C++ with the GIL released: each "
          "timestep tau = loop.step(sim.q, sim.dq, timestep), set_torque(tau), step(). Other "
          "threads may send the loop commands meanwhile. until_trajectory_done: stop early once "
          "a trajectory is no longer executing (finished, aborted or cancelled). The loop must "
          "be started and have the simulation's joints in the same order. Returns the number of "
          "steps run. Ctrl+C interrupts it (checked every 1000 steps).")
      .def(
          "push",
          [](Sim& s, const std::string& name, ArrayLike wrench, Real duration) {
            ci::Vector6d values;
            read_vector(wrench, "wrench", Length{6}, values);
            s.get().push(name, values, read_scalar(duration, "duration"));
          },
          py::arg("body_or_site"), py::arg("wrench"),
          py::arg("duration") = std::numeric_limits<double>::infinity(),
          "Applies wrench [force; torque] (6,) [N; Nm], world frame, at the origin of the named "
          "site (or body) for `duration` [s] of simulated time from the next step (default: "
          "until clear_pushes()). The point moves with the body; pushes add up.")
      .def(
          "clear_pushes", [](Sim& s) { s.get().clear_pushes(); }, "Removes every push.")
      .def(
          "site_pose", [](Sim& s, const std::string& name) { return s.get().site_pose(name); },
          py::arg("site"), "Pose of a site in the world frame (quaternion x, y, z, w).")
      .def(
          "body_pose", [](Sim& s, const std::string& name) { return s.get().body_pose(name); },
          py::arg("body"), "Pose of a body in the world frame (quaternion x, y, z, w).")
      .def(
          "contact_wrench",
          [](Sim& s, const std::string& body) {
            return vector_array(s.get().contact_wrench(body));
          },
          py::arg("body"),
          "Total contact wrench [force; torque] (6,) [N; Nm] that everything else exerts on the "
          "body (and bodies welded to it): world frame, torque about the body origin.")
      .def(
          "render_png",
          [](Sim& s, PathLike path, int width, int height, const std::string& camera) {
            const ci::sim::Simulation& simulation = s.get();
            const std::string file = read_path(path, "path");
            Claim claim(s.running, "this Simulation");
            py::gil_scoped_release release;
            simulation.render_png(file, width, height, camera);
          },
          py::arg("path"), py::arg("width") = 640, py::arg("height") = 480, py::arg("camera") = "",
          "Renders offscreen (EGL) to an RGB PNG of width x height pixels; camera: an MJCF "
          "camera name, '' = a free camera from the robot's right. Releases the GIL.")
      .def("__repr__", [](Sim& s) {
        if (s.running.load()) return std::string("Simulation(running in Simulation.run())");
        const ci::sim::Simulation& simulation = s.sim;
        return "Simulation('" + simulation.model_name() + "', " +
               std::to_string(simulation.num_joints()) +
               " joints, t = " + ci::format_number(simulation.time()) + " s, timestep " +
               ci::format_number(simulation.timestep()) + " s)";
      });

  sim.def(
      "offscreen_rendering_available",
      []() {
        std::string reason;
        const bool available = ci::sim::offscreen_rendering_available(&reason);
        return std::make_pair(available, reason);
      },
      "(available, reason): whether render_png() can work in this process, and why not.");
#endif
}
