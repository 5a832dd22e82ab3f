#pragma once
/// @file
/// YAML <-> Parameters: the YAML adapter of the parameter decoder (parameter_tree.hpp), which
/// gives every key, shape, unit, range and message; this adds what only YAML has (line numbers,
/// duplicate and merge keys, a second document, quoted or tagged scalars being strings). Part of
/// the `cartesian_impedance::config` target (yaml-cpp).

#include <string>
#include <string_view>

#include "cartesian_impedance/core/parameter_tree.hpp"
#include "cartesian_impedance/core/parameters.hpp"

namespace cartesian_impedance {

/// Reads parameters from a YAML file. Keys not given keep their defaults; keys may be nested or
/// dotted (`stiffness.translation: 500`); a per-joint or three-axis field may be given as one
/// number for all entries.
/// @throws Error for a missing or malformed file, one that is not a regular file (a FIFO, a
///         device such as /dev/zero, a directory) or is larger than kMaxFileBytes (16 MiB; see
///         core/files.hpp), an unknown or repeated key (named, with its line), a second YAML
///         document, a key that is not a plain name, a merge key, a value of the wrong shape, a
///         number or switch written as a string (quoted, tagged or a block scalar), a value
///         outside its range, more than ParameterTreeGuard::kMaxValues (100000) values or lists
///         and maps nested more than kMaxDepth (32) deep or inside themselves (aliases), or a set
///         that fails validate(). Messages are the decoder's (ParameterError) after `file:line: `.
/// What the file leaves out keeps its value in `defaults` (the library's, or those suited to a
/// robot: default_parameters(model) in model/robot_limits.hpp).
Parameters load_parameters(const std::string& path, const Parameters& defaults = Parameters{});

/// As load_parameters(), from YAML text; `source` names it in messages.
Parameters parameters_from_yaml(const std::string& yaml, std::string_view source = "<yaml>",
                                const Parameters& defaults = Parameters{});

/// The YAML text as the decoder's value tree, every value located as `source:line`, after every
/// check of the YAML itself that parameters_from_yaml() makes (malformed text, a second document,
/// keys given twice, merge keys, quoted numbers marked with a hint, the bounds of
/// ParameterTreeGuard, counted while the text is parsed), but none of the parameters'. For
/// sources that wrap parameters in a YAML file of their own (a ROS 2 params file nests them under
/// `node: ros__parameters:`).
/// @throws Error as parameters_from_yaml() for the YAML itself.
ParameterValue parameter_tree_from_yaml(const std::string& yaml, std::string_view source);

/// Writes every parameter as YAML that parameters_from_yaml() reads back to the same values.
std::string parameters_to_yaml(const Parameters& parameters);

/// Writes parameters_to_yaml() to a file. @throws Error if the file cannot be written.
void save_parameters(const std::string& path, const Parameters& parameters);

}  // namespace cartesian_impedance
