#pragma once
/// @file
/// YAML <-> Parameters, served by the parameter table (so every key, unit and range is the one
/// documented in the README). Part of the `cartesian_impedance::config` target (yaml-cpp).

#include <string>
#include <string_view>

#include "cartesian_impedance/parameters.hpp"

namespace cartesian_impedance {

/// Reads parameters from a YAML file. Keys not given keep their defaults; a per-joint or
/// three-axis field may be given as one number for all entries.
/// @throws Error for a missing or malformed file, an unknown or repeated key (named, with its
///         line), a second YAML document, a key that is not a plain name, a value of the wrong
///         shape, a number or switch written as a string (quoted, tagged or a block scalar), or
///         a value outside its range.
Parameters load_parameters(const std::string& path);

/// As load_parameters(), from YAML text; `source` names it in messages.
Parameters parameters_from_yaml(const std::string& yaml, std::string_view source = "<yaml>");

/// Writes every parameter as YAML that parameters_from_yaml() reads back to the same values.
std::string parameters_to_yaml(const Parameters& parameters);

/// Writes parameters_to_yaml() to a file. @throws Error if the file cannot be written.
void save_parameters(const std::string& path, const Parameters& parameters);

}  // namespace cartesian_impedance
