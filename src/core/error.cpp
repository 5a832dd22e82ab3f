#include "cartesian_impedance/core/error.hpp"

#include <charconv>
#include <cmath>

namespace cartesian_impedance {

namespace {

// `value` with `digits` significant digits as printf's %g writes it. to_chars and from_chars
// ignore the locale, unlike printf and streams, so a program that set a decimal comma still
// writes and reads back the same text.
std::string significant(double value, int digits) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char buffer[32];
  const auto written =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general, digits);
  return std::string(buffer, written.ptr);
}

}  // namespace

std::string format_number(double value) {
  return significant(value, 10);
}

std::string format_exact(double value) {
  if (!std::isfinite(value)) return significant(value, 1);
  // to_chars without a precision writes the shortest text that reads back exactly; in fixed
  // notation where people write numbers so (0.00001, 5000), else in scientific (1e-12).
  const double magnitude = std::abs(value);
  const bool fixed = magnitude == 0.0 || (magnitude >= 1e-5 && magnitude < 1e16);
  char buffer[32];
  const auto written =
      std::to_chars(buffer, buffer + sizeof(buffer), value,
                    fixed ? std::chars_format::fixed : std::chars_format::scientific);
  return std::string(buffer, written.ptr);
}

namespace {
constexpr const char* kAxisNames[4] = {"x", "y", "z", "w"};

std::string with_unit(double value, const char* unit) {
  std::string text = format_number(value);
  if (unit != nullptr && unit[0] != '\0') text += std::string(" ") + unit;
  return text;
}
}  // namespace

std::string to_string(const Fault& fault) {
  if (!fault) return "";
  std::string text = fault.input;
  switch (fault.form) {
    case Fault::Form::size:
      return text + " has " + format_number(fault.value) + " " +
             (fault.unit[0] != '\0' ? fault.unit : "values") + "; expected " +
             format_number(fault.bound);
    case Fault::Form::norm:
      return text + " has norm " + format_number(fault.value) +
             "; a unit quaternion is required (within " + format_number(fault.bound) + ")";
    case Fault::Form::statement:
      return text + " " + fault.reason;
    case Fault::Form::axis:
      if (fault.index >= 0 && fault.index < 4) text += std::string(".") + kAxisNames[fault.index];
      break;
    case Fault::Form::element:
      if (fault.index >= 0) text += "[" + std::to_string(fault.index) + "]";
      break;
  }
  text += " = " + with_unit(fault.value, fault.unit) + " " + fault.reason;
  if (fault.has_bound) text += " = " + with_unit(fault.bound, fault.unit);
  return text;
}

Error::Error(const Fault& fault, const std::string& message) : std::runtime_error(message) {
  keep(fault);
}

Error::Error(const Error& other) : std::runtime_error(other) {
  keep(other.fault_);
}

Error& Error::operator=(const Error& other) {
  if (this != &other) {
    std::runtime_error::operator=(other);
    keep(other.fault_);
  }
  return *this;
}

void Error::keep(const Fault& fault) {
  // Copies first: `fault` may point into this error's own strings (self-assignment aside, a
  // copy of a copy).
  std::string input = fault.input != nullptr ? fault.input : "";
  std::string reason = fault.reason != nullptr ? fault.reason : "";
  std::string unit = fault.unit != nullptr ? fault.unit : "";
  input_ = std::move(input);
  reason_ = std::move(reason);
  unit_ = std::move(unit);
  fault_ = fault;
  fault_.input = input_.c_str();
  fault_.reason = reason_.c_str();
  fault_.unit = unit_.c_str();
}

}  // namespace cartesian_impedance
