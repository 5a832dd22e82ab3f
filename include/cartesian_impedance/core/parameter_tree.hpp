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

#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
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
    invalid,       ///< the whole set fails validate() (e.g. a limit's min above its max)
    oversized      ///< a tree no parameter set can be: nested deeper than
                   ///< ParameterTreeGuard::kMaxDepth, holding itself, or holding more than
                   ///< ParameterTreeGuard::kMaxValues values (see ParameterTreeGuard)
  };
  ParameterError(Reason reason, const std::string& message) : Error(message), reason_(reason) {}
  Reason reason() const { return reason_; }

 private:
  Reason reason_;
};

/// "location: message", or the message alone if `location` is empty: how every message of a
/// parameter source is placed.
std::string with_location(std::string_view location, std::string_view message);

/// The bounds of what a source may turn into a ParameterValue tree, kept by every converter (the
/// YAML adapter, the Python dict converter, the ROS 1 XmlRpc converter) while it converts, so that
/// none recurses without end or builds a tree without bound: lists and maps nested deeper than
/// kMaxDepth, a list or map that contains itself (a Python list appended to itself, a YAML alias
/// inside its own anchor), and more than kMaxValues values are refused with a ParameterError
/// (Reason::oversized) naming the path where it was found. A converter makes one guard per tree,
/// calls count() for every value (lists and maps too) and every key, and for each list or map
/// holds the Level that enter() returns while it converts the members:
///
///     ParameterValue convert(const Source& node, const std::string& path, Guard& guard) {
///       guard.count(path, location(node));
///       if (is_list(node)) {
///         const ParameterTreeGuard::Level level = guard.enter(&node, path, location(node));
///         ...  // convert(item, path + "[i]", guard) for each item
///       }
///       ...
///     }
class ParameterTreeGuard {
 public:
  /// Lists and maps nested deeper than this are refused. A parameter is at most 4 levels below
  /// the top (limits.stiffness.translation.min), its value a list of numbers below that, and a
  /// ROS 2 params file puts two more levels on top (`node: ros__parameters:`): no parameter set
  /// nests more than 8. The rest is headroom, so that a value a few levels too deep gets the
  /// decoder's message about its shape; the bound itself keeps a converter's recursion far from
  /// the end of any thread's stack.
  static constexpr std::size_t kMaxDepth = 32;
  /// The most values a tree may hold, counting every number, string, boolean, empty value, list,
  /// map and key: a parameter set holds a few hundred; a YAML alias may repeat a list or map, and
  /// a short text then names millions.
  static constexpr std::size_t kMaxValues = 100000;

  /// One list or map being converted; leaving the scope leaves it. Made only by enter().
  class [[nodiscard]] Level {
   public:
    Level(const Level&) = delete;
    Level& operator=(const Level&) = delete;
    ~Level();

   private:
    friend class ParameterTreeGuard;
    explicit Level(ParameterTreeGuard& guard) : guard_(guard) {}
    ParameterTreeGuard& guard_;
  };

  /// Enters the list or map at `path` ("stiffness.translation[2]"; "" for the top level).
  /// `identity` is what makes it the same object in the source (the PyObject*, the
  /// YAML node's storage), or nullptr for a source whose values cannot contain themselves.
  /// @throws ParameterError (Reason::oversized) with `location` in front of the message, if the
  ///         list or map is nested deeper than kMaxDepth, is one of those it is inside of (a
  ///         cycle: the message names both paths).
  Level enter(const void* identity, const std::string& path, std::string_view location = {});

  /// Counts one value or key at `path`. @throws ParameterError (Reason::oversized) on the value
  /// after kMaxValues.
  void count(const std::string& path, std::string_view location = {});

  /// How many lists and maps are being converted (the depth of the current one).
  std::size_t depth() const { return open_.size(); }

 private:
  std::vector<std::pair<const void*, std::string>> open_;  // identity and path, outermost first
  std::size_t values_ = 0;
};

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

/// The partial update `tree` describes (see ParameterUpdate): the rows it names, with the values of
/// decode_parameters(tree, base, source), which also checks them. `base` should be the parameters
/// in force, so that the update's rules (a limit's min <= max, ...) are checked against them; the
/// update changes only the named rows wherever it is applied.
/// @throws ParameterError as decode_parameters().
ParameterUpdate decode_parameter_update(const ParameterValue& tree, const Parameters& base,
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
                        std::string_view what, const std::vector<std::string_view>& valid = {});

/// "base" or "end_effector" (see decode_name()); frame_from_name() for a plain string.
Frame decode_frame(const ParameterValue& value, std::string_view element);

/// What names the elements of a 3-vector parameter: `workspace.min` + ".x".
inline constexpr const char* kAxisSuffix[3] = {".x", ".y", ".z"};

}  // namespace cartesian_impedance
