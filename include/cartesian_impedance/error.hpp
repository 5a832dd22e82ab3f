#pragma once
/// @file
/// The exception types the library throws: Error, and two refinements for callers that act
/// differently on them (QueueFull: retry later; LoadError: fix the file). Only setters, loaders
/// and constructors throw; the control cycle never does (it reports a status instead).

#include <stdexcept>
#include <string>

namespace cartesian_impedance {

/// Raised for every rejected input: the message names the field, the offending value and the
/// valid range, e.g. `stiffness.translation.x = -5 N/m is outside [0, inf)`. A call that throws
/// changes nothing.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
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
