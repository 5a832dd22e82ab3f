// Python <-> Eigen conversions of the Python bindings (declared and documented in
// conversions.hpp).

#include "conversions.hpp"

#include <algorithm>
#include <sstream>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::python {

// ---- Python -> Eigen -------------------------------------------------------------------------

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

namespace {

const py::object& numpy_asarray() {
  // Never destroyed: a static py::object would be released after the interpreter has gone.
  static const py::object* function = new py::object(py::module_::import("numpy").attr("asarray"));
  return *function;
}

}  // namespace

bool is_sequence(py::handle object) {
  return PyList_Check(object.ptr()) || PyTuple_Check(object.ptr());
}

bool is_mapping(py::handle object) {
  static const py::object* mapping =
      new py::object(py::module_::import("collections.abc").attr("Mapping"));
  return PyDict_Check(object.ptr()) || py::isinstance(object, *mapping);
}

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

std::string expected_shape(Length length) {
  if (length.size >= 0) return "(" + std::to_string(length.size) + ",)";
  if (length.max_size == kUnbounded) return "(n,) with n >= 1";
  return "(n,) with 1 <= n <= " + std::to_string(length.max_size);
}

bool length_ok(Eigen::Index size, Length length) {
  return length.size >= 0 ? size == length.size : size >= 1 && size <= length.max_size;
}

bool is_array_like_vector(py::handle object) {
  return is_sequence(object) || (py::isinstance<py::array>(object) &&
                                 py::reinterpret_borrow<py::array>(object).ndim() > 0);
}

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

namespace {

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

}  // namespace

Eigen::Quaterniond quaternion_xyzw(py::handle object, std::string_view name) {
  Eigen::Vector4d xyzw;
  read_vector(object, name, Length{4}, xyzw);
  // Not normalised here: the library checks the norm (within 1e-3) wherever a pose is commanded.
  return Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
}

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
std::string trajectory_text(const ci::TrajectoryProgress& progress) {
  std::string text = ci::to_string(progress.state);
  if (progress.state != ci::TrajectoryState::idle) {
    text += " (id " + std::to_string(progress.id) + ", " + ci::format_number(progress.time) +
            " of " + ci::format_number(progress.duration) + " s)";
  }
  return text;
}
}  // namespace cartesian_impedance::python
