#include "cartesian_impedance/core/parameter_tree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>
#include <vector>

namespace cartesian_impedance {
namespace {

using Reason = ParameterError::Reason;

[[noreturn]] void fail(Reason reason, std::string_view location, const std::string& message) {
  throw ParameterError(reason, with_location(location, message));
}

// " [N/m]" after "is not a number", nothing for dimensionless rows and names.
std::string unit_suffix(const ParameterInfo& row) {
  return row.unit.empty() || row.unit == "-" ? "" : " [" + std::string(row.unit) + "]";
}

std::string hint_suffix(const ParameterValue& value) {
  return value.hint.empty() ? "" : " (" + value.hint + ")";
}

std::string join(std::string_view prefix, std::string_view key) {
  std::string path(prefix);
  if (!path.empty()) path += ".";
  return path += key;
}

// `location`: the value's own, or for a member of a map its key's.
void require_value(const ParameterValue& value, std::string_view element,
                   std::string_view location) {
  if (value.is(ParameterValue::Kind::empty)) {
    fail(Reason::no_value, location, std::string(element) + " has no value");
  }
}

[[noreturn]] void wrong_shape(const ParameterValue& value, std::string_view name,
                              const std::string& expected) {
  fail(Reason::wrong_shape, value.location,
       std::string(name) + " must be " + expected + ", got " + value.describe());
}

Eigen::Vector3d decode_axes(const ParameterValue& value, const ParameterInfo& row) {
  using Kind = ParameterValue::Kind;
  if (value.is(Kind::map) || (value.is(Kind::list) && value.as_list().size() != 3)) {
    wrong_shape(value, row.name, "3 numbers [x, y, z] or one number");
  }
  if (!value.is(Kind::list)) return Eigen::Vector3d::Constant(decode_number(value, row, row.name));
  Eigen::Vector3d axes;
  for (int i = 0; i < 3; ++i) {
    axes[i] = decode_number(value.as_list()[static_cast<std::size_t>(i)], row,
                            std::string(row.name) + kAxisSuffix[i]);
  }
  return axes;
}

JointVector decode_joints(const ParameterValue& value, const ParameterInfo& row) {
  using Kind = ParameterValue::Kind;
  const bool list = value.is(Kind::list);
  if (list && value.as_list().empty() && may_come_from_the_robot(row.name)) return JointVector();
  if (value.is(Kind::map) ||
      (list && (value.as_list().empty() || value.as_list().size() > kMaxJoints))) {
    wrong_shape(
        value, row.name,
        "one number or a list of 1 to " + std::to_string(kMaxJoints) + " numbers (one per joint)");
  }
  if (!list) return JointVector::Constant(1, decode_number(value, row, row.name));
  const ParameterList& items = value.as_list();
  JointVector joints(static_cast<Eigen::Index>(items.size()));
  for (std::size_t i = 0; i < items.size(); ++i) {
    joints[static_cast<Eigen::Index>(i)] =
        decode_number(items[i], row, std::string(row.name) + "[" + std::to_string(i) + "]");
  }
  return joints;
}

bool decode_switch(const ParameterValue& value, std::string_view element) {
  require_value(value, element, value.location);
  if (!value.is(ParameterValue::Kind::boolean)) {
    fail(Reason::wrong_type, value.location,
         std::string(element) + " = " + value.describe() + " is not true or false" +
             hint_suffix(value));
  }
  return value.as_boolean();
}

// Decodes `value` for `row` into `parameters`; the field changes only if nothing throws.
void decode_field(const ParameterInfo& row, const ParameterValue& value, Parameters& parameters) {
  const ParameterField field = row.in(parameters);
  if (auto* number = std::get_if<double*>(&field)) {
    **number = decode_number(value, row, row.name);
  } else if (auto* axes = std::get_if<Eigen::Vector3d*>(&field)) {
    **axes = decode_axes(value, row);
  } else if (auto* joints = std::get_if<JointVector*>(&field)) {
    **joints = decode_joints(value, row);
  } else if (const std::vector<std::string_view> names = choice_names(field); !names.empty()) {
    const char* what = std::holds_alternative<Frame*>(field) ? "a frame" : "a collision reaction";
    set_choice(field, row.name, decode_name(value, row.name, what, names));
  } else if (auto* flag = std::get_if<bool*>(&field)) {
    **flag = decode_switch(value, row.name);
  }
}

// Walks a tree's maps, assigning every leaf; remembers where each parameter was given.
class Decoder {
 public:
  explicit Decoder(Parameters& parameters) : parameters_(parameters) {}

  // The rows read so far.
  ParameterNames given() const {
    ParameterNames names;
    for (const auto& [name, where] : given_) names[parameter_index(*find_parameter(name))] = true;
    return names;
  }

  void read_map(const ParameterValue& map, const std::string& prefix) {
    for (const ParameterMember& member : map.as_map()) {
      const std::string path = join(prefix, member.key);
      const ParameterValue& value = member.value;
      const std::string& where = member.key_location.empty() ? value.location : member.key_location;
      if (const ParameterInfo* row = find_parameter(path)) {
        require_value(value, path, where);
        const auto [first, inserted] = given_.emplace(row->name, where);
        if (!inserted) {
          fail(Reason::given_twice, where,
               "'" + path + "' is given twice" +
                   (first->second.empty() ? "" : " (first at " + first->second + ")") +
                   "; expected each key once");
        }
        decode_field(*row, value, parameters_);
      } else if (!is_parameter_group(path)) {
        throw unknown_parameter(path, where);
      } else if (value.is(ParameterValue::Kind::map)) {
        read_map(value, path);
      } else if (!value.is(ParameterValue::Kind::empty)) {  // empty: every member left out
        throw unknown_parameter(path, where);
      }
    }
  }

 private:
  Parameters& parameters_;
  std::map<std::string_view, std::string> given_;  // row name -> where it was given
};

ParameterValue located(ParameterValue value, std::string location) {
  value.location = std::move(location);
  return value;
}

}  // namespace

// ---- ParameterValue ----------------------------------------------------------------------------

ParameterValue ParameterValue::number(double value, std::string location) {
  ParameterValue result;
  result.data_ = value;
  return located(std::move(result), std::move(location));
}

ParameterValue ParameterValue::too_large(std::string text, bool negative, std::string location) {
  ParameterValue result = number(
      negative ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity(),
      std::move(location));
  result.overflow_ = std::move(text);
  return result;
}

ParameterValue ParameterValue::boolean(bool value, std::string location) {
  ParameterValue result;
  result.data_ = value;
  return located(std::move(result), std::move(location));
}

ParameterValue ParameterValue::string(std::string value, std::string location) {
  ParameterValue result;
  result.data_ = std::move(value);
  return located(std::move(result), std::move(location));
}

ParameterValue ParameterValue::list(ParameterList items, std::string location) {
  ParameterValue result;
  result.data_ = std::move(items);
  return located(std::move(result), std::move(location));
}

ParameterValue ParameterValue::map(ParameterMap members, std::string location) {
  ParameterValue result;
  result.data_ = std::move(members);
  return located(std::move(result), std::move(location));
}

const ParameterValue* ParameterValue::member(std::string_view key) const {
  if (!is(Kind::map)) return nullptr;
  for (const ParameterMember& entry : as_map()) {
    if (entry.key == key) return &entry.value;
  }
  return nullptr;
}

std::string ParameterValue::describe() const {
  switch (kind()) {
    case Kind::empty:
      return "nothing";
    case Kind::number:
      return overflow_.empty() ? format_number(as_number()) : overflow_;
    case Kind::boolean:
      return as_boolean() ? "true" : "false";
    case Kind::string:
      return "'" + as_string() + "'";
    case Kind::list:
      return "a list of " + std::to_string(as_list().size());
    case Kind::map:
      break;
  }
  return "a map";
}

bool ParameterValue::operator==(const ParameterValue& other) const {
  return overflow_ == other.overflow_ && data_ == other.data_;
}

bool operator==(const ParameterMember& a, const ParameterMember& b) {
  return a.key == b.key && a.value == b.value;
}

// ---- decoding -------------------------------------------------------------------------------

std::string with_location(std::string_view location, std::string_view message) {
  std::string text(location);
  if (!text.empty()) text += ": ";
  return text += message;
}

// ---- ParameterTreeGuard -----------------------------------------------------------------------

namespace {

std::string quoted_path(const std::string& path) {
  return path.empty() ? std::string("the top level") : "'" + path + "'";
}

}  // namespace

ParameterTreeGuard::Level::~Level() {
  guard_.open_.pop_back();
}

ParameterTreeGuard::Level ParameterTreeGuard::enter(const void* identity, const std::string& path,
                                                    std::string_view location) {
  if (identity != nullptr) {
    for (const auto& [open, open_path] : open_) {
      if (open == identity) {
        fail(Reason::oversized, location,
             quoted_path(path) + " is " + quoted_path(open_path) +
                 " again: a list or map that contains itself has no end; a parameter value is "
                 "a tree");
      }
    }
  }
  if (open_.size() >= kMaxDepth) {
    fail(Reason::oversized, location,
         quoted_path(path) + " is nested too deeply: more than " + std::to_string(kMaxDepth) +
             " levels of lists and maps; parameters are nested at most " +
             std::to_string(parameter_table_depth()) +
             " levels deep, with a list of numbers below");
  }
  open_.emplace_back(identity, path);
  return Level(*this);
}

void ParameterTreeGuard::count(const std::string& path, std::string_view location) {
  if (++values_ > kMaxValues) {
    fail(Reason::oversized, location,
         "more than " + std::to_string(kMaxValues) + " values (the next at " + quoted_path(path) +
             "); a parameter set holds a few hundred");
  }
}

namespace {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] != b[j - 1] ? 1u : 0u)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// The names one level below `group` ("" = the top level), in table order: members and subgroups.
std::vector<std::string> names_under(std::string_view group) {
  std::vector<std::string> names;
  for (const ParameterInfo& info : parameter_table()) {
    std::string_view name = info.name;
    if (!group.empty()) {
      if (name.size() <= group.size() || name.substr(0, group.size()) != group ||
          name[group.size()] != '.') {
        continue;
      }
      name.remove_prefix(group.size() + 1);
    }
    const std::string first(name.substr(0, name.find('.')));
    if (std::find(names.begin(), names.end(), first) == names.end()) names.push_back(first);
  }
  return names;
}

// What the user may have meant by the unknown `path`: the closest parameter or group name (a
// typo's worth of edits away), and the valid names at the level where the path went wrong.
std::string suggestions(std::string_view path) {
  std::string text;
  if (is_parameter_group(path)) {
    text = " (it is a group; give its members: ";
    const std::vector<std::string> members = names_under(path);
    for (std::size_t i = 0; i < members.size(); ++i) text += (i > 0 ? ", " : "") + members[i];
    return text + ")";
  }
  std::string closest;
  std::size_t best = std::max<std::size_t>(2, path.size() / 5) + 1;
  auto consider = [&](std::string_view candidate) {
    // A group the path already starts with is where it went wrong, not what was meant.
    if (path.size() > candidate.size() && path.substr(0, candidate.size()) == candidate) return;
    const std::size_t distance = edit_distance(path, candidate);
    if (distance < best) {
      best = distance;
      closest = candidate;
    }
  };
  for (const ParameterInfo& info : parameter_table()) {
    consider(info.name);
    for (std::size_t dot = info.name.find('.'); dot != std::string_view::npos;
         dot = info.name.find('.', dot + 1)) {
      consider(info.name.substr(0, dot));
    }
  }
  if (!closest.empty()) text = " (did you mean '" + closest + "'?";
  // The deepest known group the path starts with: its members are what could come next.
  std::string_view group;
  for (std::size_t dot = path.find('.'); dot != std::string_view::npos;
       dot = path.find('.', dot + 1)) {
    if (!is_parameter_group(path.substr(0, dot))) break;
    group = path.substr(0, dot);
  }
  const std::vector<std::string> names = names_under(group);
  text += text.empty() ? " (valid " : " valid ";
  text += group.empty() ? std::string("top-level names: ") : "in '" + std::string(group) + "': ";
  for (std::size_t i = 0; i < names.size(); ++i) text += (i > 0 ? ", " : "") + names[i];
  return text + ")";
}

}  // namespace

ParameterError unknown_parameter(std::string_view path, std::string_view location) {
  return ParameterError(
      Reason::unknown_name,
      with_location(location, "unknown parameter '" + std::string(path) + "'" + suggestions(path)));
}

double decode_number(const ParameterValue& value, const ParameterInfo& row,
                     std::string_view element) {
  require_value(value, element, value.location);
  const std::string name(element);
  if (!value.overflow_text().empty()) {
    fail(Reason::out_of_range, value.location,
         name + " = " + value.overflow_text() + " overflows a double (valid: " + row.range_text() +
             ")");
  }
  if (!value.is(ParameterValue::Kind::number)) {
    fail(Reason::wrong_type, value.location,
         name + " = " + value.describe() + " is not a number" + unit_suffix(row) +
             hint_suffix(value));
  }
  try {
    row.check(name, value.as_number());
  } catch (const Error& error) {
    fail(Reason::out_of_range, value.location, error.what());
  }
  return value.as_number();
}

int decode_integer(const ParameterValue& value, const ParameterInfo& row,
                   std::string_view element) {
  const double number = decode_number(value, row, element);
  if (number != std::floor(number) || std::abs(number) > std::numeric_limits<int>::max()) {
    fail(Reason::wrong_type, value.location,
         std::string(element) + " = " + value.describe() + " is not a whole number");
  }
  return static_cast<int>(number);
}

std::string decode_name(const ParameterValue& value, std::string_view element,
                        std::string_view what, const std::vector<std::string_view>& valid) {
  require_value(value, element, value.location);
  const bool is_string = value.is(ParameterValue::Kind::string);
  bool listed = valid.size() == 0;
  std::string choices;
  for (std::string_view choice : valid) {
    listed = listed || (is_string && value.as_string() == choice);
    choices += (choices.empty() ? " (valid: " : ", ") + std::string(choice);
  }
  if (!is_string || !listed) {
    fail(is_string ? Reason::out_of_range : Reason::wrong_type, value.location,
         std::string(element) + " = " + value.describe() + " is not " + std::string(what) +
             (choices.empty() ? "" : choices + ")") + (is_string ? "" : hint_suffix(value)));
  }
  return value.as_string();
}

Frame decode_frame(const ParameterValue& value, std::string_view element) {
  const std::string name = decode_name(value, element, "a frame",
                                       {frame_name(Frame::base), frame_name(Frame::end_effector)});
  return name == frame_name(Frame::base) ? Frame::base : Frame::end_effector;
}

void assign_parameter(Parameters& parameters, std::string_view name, const ParameterValue& value) {
  const ParameterInfo* row = find_parameter(name);
  if (row == nullptr) throw unknown_parameter(name, value.location);
  decode_field(*row, value, parameters);
}

namespace {

Parameters decode_onto(const ParameterValue& tree, const Parameters& base, std::string_view source,
                       ParameterNames* given) {
  Parameters parameters = base;
  Decoder decoder(parameters);
  if (tree.is(ParameterValue::Kind::map)) {
    decoder.read_map(tree, "");
  } else if (!tree.is(ParameterValue::Kind::empty)) {
    fail(Reason::wrong_type, tree.location,
         "the top level must be a map of parameters, got " + tree.describe());
  }
  try {
    validate(parameters);
  } catch (const Error& error) {
    fail(Reason::invalid, source, error.what());
  }
  if (given != nullptr) *given = decoder.given();
  return parameters;
}

}  // namespace

Parameters decode_parameters(const ParameterValue& tree, const Parameters& base,
                             std::string_view source) {
  return decode_onto(tree, base, source, nullptr);
}

ParameterUpdate decode_parameter_update(const ParameterValue& tree, const Parameters& base,
                                        std::string_view source) {
  ParameterUpdate update;
  update.values = decode_onto(tree, base, source, &update.names);
  return update;
}

// ---- encoding -------------------------------------------------------------------------------

ParameterValue encode_parameter(const Parameters& parameters, const ParameterInfo& row) {
  // The table hands out mutable pointers only; reading through them changes nothing.
  const ParameterField field = row.in(const_cast<Parameters&>(parameters));
  const auto numbers = [](const auto& vector) {
    ParameterList items;
    for (Eigen::Index i = 0; i < vector.size(); ++i) {
      items.push_back(ParameterValue::number(vector[i]));
    }
    return ParameterValue::list(std::move(items));
  };
  if (auto* number = std::get_if<double*>(&field)) return ParameterValue::number(**number);
  if (auto* axes = std::get_if<Eigen::Vector3d*>(&field)) return numbers(**axes);
  if (auto* joints = std::get_if<JointVector*>(&field)) return numbers(**joints);
  if (!choice_name(field).empty()) return ParameterValue::string(std::string(choice_name(field)));
  return ParameterValue::boolean(*std::get<bool*>(field));
}

ParameterValue encode_parameters(const Parameters& parameters, KeyLayout layout) {
  ParameterValue root = ParameterValue::map({});
  for (const ParameterInfo& row : parameter_table()) {
    ParameterValue* group = &root;
    std::string_view name = row.name;
    for (std::size_t dot;
         layout == KeyLayout::nested && (dot = name.find('.')) != std::string_view::npos;
         name.remove_prefix(dot + 1)) {
      // The table lists the members of a group together: the group is the last member or new.
      ParameterMap& members = group->as_map();
      const std::string_view key = name.substr(0, dot);
      if (members.empty() || members.back().key != key) {
        members.push_back({std::string(key), ParameterValue::map({}), {}});
      }
      group = &members.back().value;
    }
    group->as_map().push_back({std::string(name), encode_parameter(parameters, row), {}});
  }
  return root;
}

}  // namespace cartesian_impedance
