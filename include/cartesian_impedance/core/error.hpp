#pragma once
/// @file
/// What the library reports about bad input, as data and as text. A `Fault` names one input that
/// is wrong (field, element, value, the bound it broke); the checks (checks.hpp) return one, the
/// control cycle reports one when it fails closed, and `Error`, the exception every setter,
/// loader and constructor throws, carries one. Only those throw; the cycle never does.

#include <stdexcept>
#include <string>

namespace cartesian_impedance {

/// A number as every message of the library shows it: at most 10 significant digits, without
/// trailing zeros (0.5, 6.283185307, 1000000000), and nan, inf, -inf. Independent of the C and
/// C++ locales.
std::string format_number(double value);

/// A number as the library writes it to files: the shortest text that reads back as the same
/// double (0.2, not 0.20000000000000001), in fixed notation from 1e-5 to 1e16 (0.00001,
/// 1000000000) and in scientific notation beyond (1e-12). Independent of the locales.
std::string format_exact(double value);

/// One input that is wrong, without allocating: a plain value the control cycle can fill and
/// copy. `input` and the texts point to storage that outlives the fault (string literals, the
/// parameter table, or the Error that carries it).
struct Fault {
  /// How to_string() reads the fault.
  enum class Form : unsigned char {
    element,    ///< "dq[4] = nan is not finite", "dt = 1e9 is above plausibility.dt.max = 0.02"
    axis,       ///< the index names an axis or component: "pose.position.y = nan m is not finite"
    size,       ///< `value` is a count, `bound` the one expected: "q has 6 values; expected 7"
    norm,       ///< `value` is a norm: "pose.orientation has norm 0.5; a unit quaternion ..."
    statement,  ///< no value: "damping cannot be shaped by the task-space inertia: ..."
  };

  const char* input = "";   ///< the field: "dt", "q", "dq", "pose.orientation", ...; "" if none
  int index = -1;           ///< element (joint, axis) index, or -1
  double value = 0.0;       ///< the offending value (for Form::size the count)
  const char* reason = "";  ///< "is not finite", "is above plausibility.dt.max", ...
  double bound = 0.0;       ///< the bound it broke, where `reason` names one
  bool has_bound = false;
  const char* unit = "";  ///< of value and bound ("rad/s"); for Form::size what is counted
  Form form = Form::element;

  /// True if there is a fault (an input is named).
  explicit operator bool() const noexcept { return input != nullptr && input[0] != '\0'; }
};

/// "dq[4] = nan is not finite", "dt = 1000000000 is above plausibility.dt.max = 0.02"; "" if
/// there is no fault.
std::string to_string(const Fault& fault);

/// Raised for every rejected input: the message names the field, the offending value and the
/// valid range, e.g. `stiffness.translation.x = -5 N/m is outside [0, inf)`. A call that throws
/// changes nothing. Where a check found the problem, fault() holds it as data (field, index,
/// value, bound), so that a caller can act on the field instead of parsing the text.
class Error : public std::runtime_error {
 public:
  /// An error without fault data (a file that cannot be read, a name that is not known).
  explicit Error(const std::string& message) : std::runtime_error(message) {}
  /// The error of `fault`, with `message` as its text (checks::raise() makes it from the fault).
  Error(const Fault& fault, const std::string& message);

  Error(const Error& other);
  Error& operator=(const Error& other);
  ~Error() override = default;

  /// The fault as data; empty (`!fault()`) for an error without one.
  const Fault& fault() const noexcept { return fault_; }

 private:
  void keep(const Fault& fault);
  // The fault's texts, owned here so that the fault outlives the storage it was made from.
  std::string input_, reason_, unit_;
  Fault fault_;
};

/// A valid command that could not be queued because the control loop's inbox stayed full (the
/// loop is not stepping, or commands arrive faster than it applies them). Unlike other errors it
/// is transient: the same command may succeed later.
class QueueFull : public Error {
 public:
  using Error::Error;
};

/// A file or text that describes the robot or its configuration (URDF, YAML parameters) could not
/// be read, is malformed, or does not hold what was asked of it (a link name it lacks, a value
/// out of range); the message names the file (and the line where known) and what is wrong.
/// Arguments given beside it that are wrong on their own (a non-finite tool offset) are Errors.
class LoadError : public Error {
 public:
  using Error::Error;
};

}  // namespace cartesian_impedance
