#pragma once
/// @file
/// The one decoder of the parameter tree, whatever the source. A source (the YAML loader, the ROS
/// parameter server, a Python dict, a ROS 2 params file) only turns its own values into a
/// ParameterValue tree, with a location for messages where it knows one, and calls
/// decode_parameters() (or assign_parameter() for one name). Every shape a parameter accepts and
/// every message about a value of the wrong type, shape or range is written here once:
///
/// | field (see ParameterField) | accepts                                                  |
/// |---|---|
/// | number                     | a number                                                 |
/// | three axes (x, y, z)       | a number (all three axes) or a list of 3 numbers         |
/// | per joint                  | a number (every joint) or a list of 1 to kMaxJoints numbers |
/// | frame                      | the string "base" or "end_effector"                      |
/// | switch                     | true or false (a boolean; not a number, not a string)    |
///
/// Numbers are in the units of the parameter table (SI: N/m, Nm/rad, s, ...; the table and the
/// README list them) and are not converted; messages print the unit after the value. Numbers
/// must be finite and in the row's range (ParameterInfo::check()). Integers are numbers;
/// booleans and strings are not, even if a string reads as a number (a source that parses text,
/// like YAML, decides what is a string before the decoder sees it). Part of the core library: no
/// YAML, ROS or Python dependency.

#include <initializer_list>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"

namespace cartesian_impedance {

class ParameterValue;
struct ParameterMember;
/// The items of a list value, in order.
using ParameterList = std::vector<ParameterValue>;
/// The members of a map value, in the source's order (keys are not sorted or merged).
using ParameterMap = std::vector<ParameterMember>;

/// What any source gives for a value: nothing, a number, a boolean, a string, a list or a map,
/// plus where it was found. Built with the static factories; a default-constructed value is empty
/// (YAML `~`, Python None, an unset XmlRpc value).
class ParameterValue {
 public:
  enum class Kind { empty, number, boolean, string, list, map };

  ParameterValue() = default;
  static ParameterValue number(double value, std::string location = {});
  /// A number too large for a double, as the source wrote it ("1e400", Python's 10**400): it
  /// decodes to an error naming `text` and the row's range, not to infinity.
  static ParameterValue too_large(std::string text, bool negative = false,
                                  std::string location = {});
  static ParameterValue boolean(bool value, std::string location = {});
  static ParameterValue string(std::string value, std::string location = {});
  static ParameterValue list(ParameterList items, std::string location = {});
  static ParameterValue map(ParameterMap members, std::string location = {});

  Kind kind() const { return static_cast<Kind>(data_.index()); }
  bool is(Kind kind) const { return this->kind() == kind; }
  /// The content; each requires the matching kind (else std::bad_variant_access).
  double as_number() const { return std::get<double>(data_); }
  bool as_boolean() const { return std::get<bool>(data_); }
  const std::string& as_string() const { return std::get<std::string>(data_); }
  const ParameterList& as_list() const { return std::get<ParameterList>(data_); }
  const ParameterMap& as_map() const { return std::get<ParameterMap>(data_); }
  ParameterList& as_list() { return std::get<ParameterList>(data_); }
  ParameterMap& as_map() { return std::get<ParameterMap>(data_); }
  /// The first member called `key` of a map; nullptr if there is none or this is not a map.
  const ParameterValue* member(std::string_view key) const;
  /// The source's text of a too_large() number; empty for every other value.
  const std::string& overflow_text() const { return overflow_; }

  /// How messages show the value: `nothing`, `0.5`, `true`, `'tool'`, `a list of 2`, `a map`.
  std::string describe() const;

  /// Same kind and content (numbers compared as doubles); locations and hints do not count.
  bool operator==(const ParameterValue& other) const;
  bool operator!=(const ParameterValue& other) const { return !(*this == other); }

  /// Where the value was found, put in front of messages about it: "panda.yaml:12",
  /// "ROS parameter /arm/controller/stiffness/translation". Empty: no prefix.
  std::string location;
  /// Why the source gave this kind, added to a message that rejects the kind, e.g. YAML's
  /// "it is quoted ..., which makes it a string in YAML: write it without quotes". Usually empty.
  std::string hint;

 private:
  std::variant<std::monostate, double, bool, std::string, ParameterList, ParameterMap> data_;
  std::string overflow_;
};

/// One entry of a map value. `key` is one level ("translation") or several joined by dots
/// ("stiffness.translation"); `key_location` places messages about the key itself (unknown,
/// given twice, no value), falling back to the value's location.
struct ParameterMember {
  std::string key;
  ParameterValue value;
  std::string key_location;
};

/// Same key and value; key locations do not count.
bool operator==(const ParameterMember& a, const ParameterMember& b);

/// Every error of decoding: the library's Error (the message names the dotted key, the value, what
/// is expected and the location when known), with the reason, so that an adapter can map it onto
/// its own error types (e.g. TypeError in Python).
class ParameterError : public Error {
 public:
  enum class Reason {
    unknown_name,  ///< a key that is no parameter and no group of parameters
    no_value,      ///< empty where a value is needed
    wrong_type,    ///< e.g. a string or a boolean where a number is needed
    wrong_shape,   ///< a list of the wrong length, a map where a value is needed
    out_of_range,  ///< a number outside its row's range, not finite or too large for a double;
                   ///< a name that is none of the valid ones
    given_twice,   ///< one parameter reached by two keys (a dotted one and a nested one)
    invalid        ///< the whole set fails validate() (e.g. a limit's min above its max)
  };
  ParameterError(Reason reason, const std::string& message) : Error(message), reason_(reason) {}
  Reason reason() const { return reason_; }

 private:
  Reason reason_;
};

/// "location: message", or the message alone if `location` is empty: how every message of a
/// parameter source is placed.
std::string with_location(std::string_view location, std::string_view message);

/// The error for `path`, which is no parameter: "unknown parameter 'path'", with " (it is a group;
/// give its members)" if it names a group.
ParameterError unknown_parameter(std::string_view path, std::string_view location = {});

/// Decodes `value` into the field of row `name` of `parameters` and checks the range of every
/// element. Cross-field rules (a limit's min <= max) are validate()'s: call it after assigning.
/// Only the field of `name` changes, and only if nothing is thrown.
/// @throws ParameterError for an unknown name, a value of the wrong type or shape, or an element
///         out of range, e.g.
///         `panda.yaml:3: stiffness.translation.y = -5 N/m is outside [0, 100000]`.
void assign_parameter(Parameters& parameters, std::string_view name, const ParameterValue& value);

/// `base` with every leaf of `tree` assigned, then validated. `tree` is a map of groups and
/// parameters, nested (`stiffness: {translation: 500}`), dotted (`stiffness.translation: 500`) or
/// both; an empty group is skipped; an empty tree gives `base`. `source` prefixes the messages of
/// validate(), which concern the whole set rather than one value ("panda.yaml: limits...").
/// @throws ParameterError for a top level that is not a map, an unknown key (named by its dotted
///         path; a group given a value says so), a parameter given twice or without a value, every
///         error of assign_parameter(), and a set that fails validate().
Parameters decode_parameters(const ParameterValue& tree, const Parameters& base = Parameters{},
                             std::string_view source = {});

/// How encode_parameters() names the parameters.
enum class KeyLayout {
  nested,  ///< maps of groups, as in YAML: {stiffness: {translation: [...]}}
  dotted   ///< one flat map: {"stiffness.translation": [...]}
};

/// The value of row `row` of `parameters`: a number, a list (three axes; per joint, even of one
/// value), a string (frames) or a boolean.
ParameterValue encode_parameter(const Parameters& parameters, const ParameterInfo& row);

/// Every parameter in table order, as a map that decode_parameters() reads back to the same values.
/// Writers (YAML, Python dicts, dumps) are built on it.
ParameterValue encode_parameters(const Parameters& parameters,
                                 KeyLayout layout = KeyLayout::nested);

/// One number for the element `element` of `row` (a row of the table, or one of a source's own
/// settings, e.g. the ROS node's control rate in Hz): kind and range checked, messages as for
/// every parameter. @throws ParameterError.
double decode_number(const ParameterValue& value, const ParameterInfo& row,
                     std::string_view element);

/// As decode_number(), and the number must be a whole number (e.g. a thread priority).
int decode_integer(const ParameterValue& value, const ParameterInfo& row, std::string_view element);

/// A string naming `what` ("a frame", "a link name"); if `valid` is not empty, one of those
/// ("element = 'tool' is not a frame (valid: base, end_effector)"). @throws ParameterError.
std::string decode_name(const ParameterValue& value, std::string_view element,
                        std::string_view what, std::initializer_list<std::string_view> valid = {});

/// "base" or "end_effector" (see decode_name()); frame_from_name() for a plain string.
Frame decode_frame(const ParameterValue& value, std::string_view element);

}  // namespace cartesian_impedance
