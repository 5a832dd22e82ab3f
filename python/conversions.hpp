#pragma once
// Python <-> Eigen conversions of the Python bindings, and the argument types that name in the
// signatures what they accept.
//
// Every array argument goes through these helpers, which check the type (any real dtype is
// converted to float64; bool, complex, object and string arrays are rejected with TypeError) and
// the shape (ValueError naming the argument and the expected shape) before the library sees it.
// Arrays leave as fresh NumPy copies, so nothing in Python aliases the library's storage.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <limits>
#include <optional>
#include <string>
#include <string_view>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"

namespace cartesian_impedance::python {

namespace py = pybind11;
namespace ci = cartesian_impedance;

// ---- Python -> Eigen -------------------------------------------------------------------------

/// The Python type's name, for messages.
std::string type_name(py::handle object);
/// "(2, 3)", "(4,)": an array's shape as NumPy prints it.
std::string shape_text(const py::array& array);
/// A list or a tuple.
bool is_sequence(py::handle object);
/// A dict or any collections.abc.Mapping.
bool is_mapping(py::handle object);

/// `object` as a float64 NumPy array, without a copy if it is one already. Integer and float
/// dtypes are converted; bool, complex, object, string and other dtypes raise TypeError.
py::array_t<double> real_array(py::handle object, std::string_view name);

/// Accepted length of a vector argument: exactly `size` entries, or any of 1..max_size if size < 0.
struct Length {
  Eigen::Index size = -1;
  Eigen::Index max_size = ci::kMaxJoints;
};

inline constexpr Eigen::Index kUnbounded = std::numeric_limits<Eigen::Index>::max();

/// "(6,)", "(n,) with 1 <= n <= 16": the shape `length` accepts, for messages.
std::string expected_shape(Length length);
bool length_ok(Eigen::Index size, Length length);

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

/// A list, a tuple or an array of at least one dimension.
bool is_array_like_vector(py::handle object);

/// A real number: Python float or int, a NumPy real scalar or a 0-d array (not bool).
double read_scalar(py::handle object, std::string_view name);

/// One number for all entries or a vector (per-joint fields, nullspace stiffness).
Eigen::VectorXd read_one_or_vector(py::handle object, std::string_view name, Length length);

/// A str or an os.PathLike (through os.fspath).
std::string read_path(py::handle object, std::string_view name);
/// 'base', 'end_effector', a Frame, or None (nullopt).
std::optional<ci::Frame> read_frame(py::handle object, std::string_view name);
/// A quaternion given as (4,) in the order x, y, z, w (not normalised).
Eigen::Quaterniond quaternion_xyzw(py::handle object, std::string_view name);

/// A pose given as a Pose, a pair (position (3,), quaternion x, y, z, w (4,)) or a 4x4
/// homogeneous transform.
ci::Pose read_pose(py::handle object, std::string_view name);

// ---- Eigen -> Python (always copies) ---------------------------------------------------------

py::array_t<double> vector_array(const Eigen::Ref<const Eigen::VectorXd>& vector);
py::array_t<double> matrix_array(const Eigen::Ref<const Eigen::MatrixXd>& matrix);
/// A quaternion as (4,) in the order x, y, z, w.
py::array_t<double> xyzw_array(const Eigen::Quaterniond& quaternion);
/// None for an empty vector.
py::object optional_array(const ci::JointVector& vector);
/// The 4x4 homogeneous transform of `pose` (the quaternion normalised).
Eigen::Matrix4d pose_matrix(const ci::Pose& pose);

// ---- Text for __repr__ -----------------------------------------------------------------------

/// "[1, 2.5, 3]"
std::string numbers_text(const Eigen::Ref<const Eigen::VectorXd>& values);
std::string pose_repr(const ci::Pose& pose);
/// "executing (id 3, 0.5 of 2 s)"
std::string trajectory_text(const ci::TrajectoryProgress& progress);

// ---- Argument types: any Python object, converted by the helpers above -----------------------
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

}  // namespace cartesian_impedance::python

namespace pybind11::detail {
template <>
struct handle_type_name<cartesian_impedance::python::ArrayLike> {
  static constexpr auto name = const_name("ArrayLike");
};
template <>
struct handle_type_name<cartesian_impedance::python::Real> {
  static constexpr auto name = const_name("float");
};
template <>
struct handle_type_name<cartesian_impedance::python::PoseLike> {
  static constexpr auto name = const_name("Pose | tuple[ArrayLike, ArrayLike] | ArrayLike");
};
template <>
struct handle_type_name<cartesian_impedance::python::FrameLike> {
  static constexpr auto name = const_name("str | Frame | None");
};
template <>
struct handle_type_name<cartesian_impedance::python::PathLike> {
  static constexpr auto name = const_name("str | os.PathLike");
};
template <>
struct handle_type_name<cartesian_impedance::python::ParametersLike> {
  static constexpr auto name = const_name("Parameters | dict | None");
};
template <>
struct handle_type_name<cartesian_impedance::python::Mapping> {
  static constexpr auto name = const_name("dict");
};
}  // namespace pybind11::detail
