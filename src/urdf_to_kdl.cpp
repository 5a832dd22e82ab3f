#include "urdf_to_kdl.hpp"

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <kdl/frames.hpp>
#include <kdl/joint.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/segment.hpp>
#include <limits>
#include <mutex>
#include <sstream>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "cartesian_impedance/error.hpp"

namespace cartesian_impedance::detail {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Bounds on the numbers of a URDF. They are far beyond any robot arm, so that they only catch
// typos and garbage, and small enough that nothing a model computes from them can overflow: even
// 10^4 links of the largest mass, each at the largest distance from the last, make inertias of
// about 1e24 kg m^2 (gravity torques about 1e18 Nm), far from the overflow at 1e308.
// A robot bigger than a kilometre is a unit mistake or garbage; the largest gantries span tens of
// metres.
constexpr double kMaxDistance = 1000.0;  // [m] every coordinate of an origin, a prismatic limit
// 1000 t: more than any arm with its payload (the heaviest industrial robots lift 2.3 t).
constexpr double kMaxMass = 1e6;  // [kg]
// The largest mass 1 m from its centre of mass; the links of industrial arms have below 1e3.
constexpr double kMaxInertia = 1e6;  // [kg m^2] every entry of an inertia tensor
// An axis is a direction, which URDF writes with norm 1: a norm far from it is a typo for zero or
// garbage, not a direction.
constexpr double kMinAxisNorm = 1e-9;
constexpr double kMaxAxisNorm = 1e9;
// TinyXML (urdfdom's XML parser) parses nested elements recursively, a few hundred bytes of stack
// per level (measured: 1 MB of stack overflows at 4000 to 8000 levels), so the nesting depth of
// a file must be bounded before it is parsed. A URDF needs 5 levels (robot/link/visual/geometry/
// mesh), simulator extensions a few more; 100 levels take well under 100 kB of stack. (urdfdom
// itself links the tree in loops over joints and links, not by recursion: chains and branches of
// 100,000 links parse in a few seconds, and KDL's solvers loop over the segments too.)
constexpr std::size_t kMaxXmlDepth = 100;
// TinyXML looks each attribute up among those before it in its element, so its time grows with
// the square of an element's attributes; URDF elements have at most 6 (<inertia>).
constexpr std::size_t kMaxXmlAttributes = 64;

std::string quoted(const std::string& name) {
  return "'" + name + "'";
}

// 1-based line of byte `position` of `text`, for messages.
std::size_t line_at(const std::string& text, std::size_t position) {
  return 1 + static_cast<std::size_t>(std::count(
                 text.begin(), text.begin() + static_cast<std::ptrdiff_t>(position), '\n'));
}

// ---------------------------------------------------------------------------------------------
// The tree. urdfdom links every joint's child to its parent without checking that the joints
// form a tree: a link with two parent joints keeps one of them, and a loop of links (a joint from
// a link to itself is the shortest) makes every walk towards the root endless and leaves
// urdfdom's links owning each other. The joints are therefore checked, on the text before
// urdfdom builds anything and again on urdfdom's model.

struct TreeJoint {
  std::string name;
  std::string parent;  // link names
  std::string child;
};

// "'a' -> 'b' -> 'c'" with at most 12 names shown.
std::string name_list(const std::vector<std::string>& names, const char* separator) {
  constexpr std::size_t kShown = 12;
  std::string text;
  for (std::size_t i = 0; i < names.size() && i < kShown; ++i) {
    text += (i ? separator : "") + quoted(names[i]);
  }
  if (names.size() > kShown) {
    text += std::string(separator) + "... (" + std::to_string(names.size()) + " in all)";
  }
  return text;
}

// Throws unless `joints` form a forest: unique joint names, no joint from a link to itself, at
// most one parent joint per link and no loop. urdfdom itself requires exactly one root.
void check_tree(const std::vector<TreeJoint>& joints, const std::string& source) {
  std::unordered_map<std::string, std::size_t> by_name;
  std::unordered_map<std::string, std::size_t> parent_joint;  // child link -> joint
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const TreeJoint& joint = joints[i];
    if (!by_name.emplace(joint.name, i).second) {
      throw Error(source + " defines joint " + quoted(joint.name) +
                  " twice; expected every joint name once");
    }
    if (joint.parent == joint.child) {
      throw Error("joint " + quoted(joint.name) + " of " + source + " has link " +
                  quoted(joint.parent) +
                  " as both its parent and its child; expected two different links");
    }
    const auto [existing, inserted] = parent_joint.emplace(joint.child, i);
    if (!inserted) {
      const TreeJoint& other = joints[existing->second];
      throw Error("link " + quoted(joint.child) + " of " + source + " has two parent joints, " +
                  quoted(other.name) + " (from " + quoted(other.parent) + ") and " +
                  quoted(joint.name) + " (from " + quoted(joint.parent) +
                  "); expected a tree, in which every link has at most one parent joint");
    }
  }
  // Every link has at most one parent now, so the walk up from any link either reaches a root or
  // runs into itself. Links already known to reach a root end a walk early: linear time.
  enum class Seen { on_this_walk, reaches_root };
  std::unordered_map<std::string, Seen> seen;
  std::vector<const std::string*> walk;
  for (const TreeJoint& start : joints) {
    walk.clear();
    for (const std::string* link = &start.child;;) {
      const auto known = seen.find(*link);
      if (known != seen.end() && known->second == Seen::reaches_root) break;
      if (known != seen.end()) {
        // The loop is the part of the walk from this link on; listed from parent to child.
        std::vector<std::string> links;
        std::vector<std::string> loop_joints;
        std::size_t first = 0;
        while (*walk[first] != *link) ++first;
        for (std::size_t i = walk.size(); i-- > first;) {
          links.push_back(*walk[i]);
          loop_joints.push_back(joints[parent_joint.at(*walk[i])].name);
        }
        std::rotate(loop_joints.begin(), loop_joints.begin() + 1, loop_joints.end());
        links.push_back(links.front());
        throw Error(source + " has a loop of links, " + name_list(links, " -> ") + " (joints " +
                    name_list(loop_joints, ", ") +
                    "); expected a tree, in which every link hangs from the one root link");
      }
      seen.emplace(*link, Seen::on_this_walk);
      walk.push_back(link);
      const auto up = parent_joint.find(*link);
      if (up == parent_joint.end()) break;  // a root
      link = &joints[up->second].parent;
    }
    for (const std::string* link : walk) seen[*link] = Seen::reaches_root;
  }
}

// ---------------------------------------------------------------------------------------------
// The text before urdfdom. TinyXML 2.6 (which urdfdom uses) recurses once per nested element and
// would overflow the stack on deep nesting, and urdfdom leaks its model when a loop of links is
// followed by another error. So the text is read here first, the way TinyXML reads it, for its
// nesting depth and its joints. Where the two readings could differ, the text is rejected:
//  - a NUL byte ends TinyXML's text early;
//  - in invalid UTF-8, TinyXML takes a lead byte to cover the next bytes whatever they are, so a
//    '<' seen here could be text to it;
//  - an XML declaration has its own attribute syntax in TinyXML (quotes only around known
//    attributes), so only a plain one, first in the file, is accepted;
//  - TinyXML takes U+FEFF, U+FFFE and U+FFFF for white space, but only in some of its modes.
// Otherwise the reading follows TinyXML: comments end at "-->", CDATA at "]]>", "<!..." and
// "<" + anything but a letter, '_' or a byte >= 0x7F at the next '>'; a start tag's attributes
// are read with TinyXML's syntax, and it is empty if "/>" ends it; an end tag closes the open
// element only if it names it (TinyXML fails otherwise); text runs to the next '<'. So as long
// as TinyXML reads on, the open elements here are its open elements. A construct that is never
// closed is rejected.

class XmlPrescan {
 public:
  XmlPrescan(const std::string& xml, const std::string& source) : xml_(xml), source_(source) {}

  // Checks the text and returns the joints of urdfdom's <robot> element, with parent and child as
  // written (entities not decoded: equal here means equal to urdfdom, the converse need not hold).
  std::vector<TreeJoint> run() {
    check_bytes();
    check_character_references();
    std::size_t first_node = xml_.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
    while (first_node < xml_.size() && is_space(xml_[first_node])) ++first_node;
    std::size_t at = 0;
    while ((at = xml_.find('<', at)) != std::string::npos) {
      if (starts_with(at, "<!--")) {
        at = past(at + 4, "-->", at, "a comment (<!--)");
      } else if (starts_with(at, "<![CDATA[")) {
        at = past(at + 9, "]]>", at, "a CDATA section");
      } else if (is_declaration(at)) {
        at = declaration(at, at == first_node);
      } else if (starts_with(at, "</")) {
        at = end_tag(at);
      } else if (at + 1 < xml_.size() && is_name_start(xml_[at + 1])) {
        at = start_tag(at);
      } else {
        at = past(at + 1, ">", at, "a tag");
      }
    }
    return joints_;
  }

 private:
  static bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
  }
  // TinyXML's IsAlpha/IsAlphaNum: ASCII letters (digits), and every byte from 0x7F on.
  static bool is_name_start(char c) {
    const auto byte = static_cast<unsigned char>(c);
    return (byte >= 'a' && byte <= 'z') || (byte >= 'A' && byte <= 'Z') || byte == '_' ||
           byte >= 0x7F;
  }
  static bool is_name_char(char c) {
    return is_name_start(c) || (c >= '0' && c <= '9') || c == '-' || c == '.' || c == ':';
  }

  bool starts_with(std::size_t at, const char* prefix) const {
    return xml_.compare(at, std::char_traits<char>::length(prefix), prefix) == 0;
  }
  // Just past the next `end` from `from`. Without one, the construct begun at `at` is not closed:
  // TinyXML 2.6 fails on that, and older versions read past the end of the text.
  std::size_t past(std::size_t from, const char* end, std::size_t at, const char* what) const {
    const std::size_t found = xml_.find(end, from);
    if (found == std::string::npos) fail(at, std::string("has ") + what + " that is never closed");
    return found + std::char_traits<char>::length(end);
  }
  std::size_t name_end(std::size_t from) const {
    while (from < xml_.size() && is_name_char(xml_[from])) ++from;
    return from;
  }
  std::size_t skip_space(std::size_t from) const {
    while (from < xml_.size() && is_space(xml_[from])) ++from;
    return from;
  }

  [[noreturn]] void fail(std::size_t at, const std::string& what) const {
    throw Error(source_ + " " + what + " (line " + std::to_string(line_at(xml_, at)) + ")");
  }

  void check_bytes() const {
    const std::size_t nul = xml_.find('\0');
    if (nul != std::string::npos) fail(nul, "contains a NUL byte; expected text");
    for (std::size_t i = 0; i < xml_.size();) {
      const auto lead = static_cast<unsigned char>(xml_[i]);
      if (lead < 0x80) {
        ++i;
        continue;
      }
      // Well-formed UTF-8 (Unicode 3.9, table 3-7): no overlong forms, surrogates or code points
      // beyond U+10FFFF.
      std::size_t length = 0;
      unsigned char low = 0x80, high = 0xBF;
      if (lead >= 0xC2 && lead <= 0xDF) {
        length = 2;
      } else if (lead >= 0xE0 && lead <= 0xEF) {
        length = 3;
        if (lead == 0xE0) low = 0xA0;
        if (lead == 0xED) high = 0x9F;
      } else if (lead >= 0xF0 && lead <= 0xF4) {
        length = 4;
        if (lead == 0xF0) low = 0x90;
        if (lead == 0xF4) high = 0x8F;
      }
      bool valid = length > 0 && i + length <= xml_.size();
      for (std::size_t k = 1; valid && k < length; ++k) {
        const auto byte = static_cast<unsigned char>(xml_[i + k]);
        valid = k == 1 ? byte >= low && byte <= high : byte >= 0x80 && byte <= 0xBF;
      }
      if (!valid) {
        std::ostringstream what;
        what << "is not valid UTF-8 (byte 0x" << std::hex << static_cast<int>(lead) << " at offset "
             << std::dec << i << ")";
        fail(i, what.str());
      }
      // TinyXML skips these three as white space (where a quote may then open a value that it
      // would otherwise not); a byte order mark is fine at the very start only.
      if (i > 0 &&
          (xml_.compare(i, 3, "\xEF\xBB\xBF") == 0 || xml_.compare(i, 3, "\xEF\xBF\xBE") == 0 ||
           xml_.compare(i, 3, "\xEF\xBF\xBF") == 0)) {
        fail(i, "contains U+FEFF, U+FFFE or U+FFFF after its start; expected none");
      }
      i += length;
    }
  }

  // TinyXML reads "&#" + digits + ';' as a character, looking for the ';' with strchr: without one
  // close by, that search runs to the end of the text for every "&#", which takes quadratic time.
  // So every "&#" must begin a well-formed reference, in comments too (harmless there).
  void check_character_references() const {
    for (std::size_t at = xml_.find("&#"); at != std::string::npos; at = xml_.find("&#", at + 2)) {
      const bool hex = at + 2 < xml_.size() && xml_[at + 2] == 'x';
      const std::size_t first = at + (hex ? 3 : 2);
      std::size_t i = first;
      while (i < xml_.size() && i - first < 8 &&
             (hex ? std::isxdigit(static_cast<unsigned char>(xml_[i])) != 0
                  : xml_[i] >= '0' && xml_[i] <= '9')) {
        ++i;
      }
      if (i == first || i >= xml_.size() || xml_[i] != ';') {
        fail(at,
             "has a character reference that is not &#digits; or &#xhexdigits; (with at most "
             "8 digits)");
      }
    }
  }

  // TinyXML takes "<?xml", in any case, for a declaration.
  bool is_declaration(std::size_t at) const {
    if (!starts_with(at, "<?") || at + 5 > xml_.size()) return false;
    for (std::size_t i = 0; i < 3; ++i) {
      const char c = xml_[at + 2 + i];
      if ((c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c) != "xml"[i]) return false;
    }
    return true;
  }

  // <?xml (name="value" | name='value')* ?> with no '<' or '>' in the values: TinyXML ends such a
  // declaration at its first '>', as this reading does.
  std::size_t declaration(std::size_t at, bool first) const {
    if (!first) {
      fail(at,
           "has an XML declaration (<?xml ...?>) that does not come first; it may only come "
           "first");
    }
    std::size_t i = at + 5;
    while (true) {
      const std::size_t next = skip_space(i);
      if (starts_with(next, "?>")) return next + 2;
      if (next == i || next >= xml_.size() || !is_name_start(xml_[next])) malformed(at);
      i = skip_space(name_end(next));
      if (i >= xml_.size() || xml_[i] != '=') malformed(at);
      i = skip_space(i + 1);
      if (i >= xml_.size() || (xml_[i] != '"' && xml_[i] != '\'')) malformed(at);
      const char quote = xml_[i];
      for (++i; i < xml_.size() && xml_[i] != quote; ++i) {
        if (xml_[i] == '<' || xml_[i] == '>') malformed(at);
      }
      if (i >= xml_.size()) malformed(at);
      ++i;
    }
  }
  [[noreturn]] void malformed(std::size_t at) const {
    fail(at,
         "has an XML declaration that is not of the form <?xml version=\"1.0\" ...?> with quoted "
         "attribute values");
  }

  std::size_t start_tag(std::size_t at) {
    const std::size_t name_begin = at + 1;
    const std::size_t name_stop = name_end(name_begin);
    // The attributes as TinyXML reads them: a name, '=', and a value either quoted (up to the same
    // quote) or not (up to white space, '/' or '>', quotes included). Where TinyXML would fail,
    // this reading steps on by a byte: TinyXML reads no further, so nothing after matters.
    std::size_t end = name_stop;
    bool empty = false;
    std::size_t attributes = 0;
    while (true) {
      end = skip_space(end);
      if (end >= xml_.size()) fail(at, "has a tag that is never closed");
      const char c = xml_[end];
      if (c == '>') break;
      if (c == '/' && end + 1 < xml_.size() && xml_[end + 1] == '>') {
        empty = true;
        ++end;
        break;
      }
      if (!is_name_start(c)) {
        ++end;
        continue;
      }
      end = skip_space(name_end(end));
      if (end >= xml_.size() || xml_[end] != '=') continue;
      if (++attributes > kMaxXmlAttributes) {
        fail(at, "has an element with more than " + std::to_string(kMaxXmlAttributes) +
                     " attributes; a URDF element has at most 6");
      }
      end = skip_space(end + 1);
      if (end < xml_.size() && (xml_[end] == '"' || xml_[end] == '\'')) {
        const std::size_t close = xml_.find(xml_[end], end + 1);
        if (close == std::string::npos) {
          fail(end, "has a quoted attribute value that is never closed");
        }
        end = close + 1;
      } else {
        while (end < xml_.size() && !is_space(xml_[end]) && xml_[end] != '/' && xml_[end] != '>') {
          ++end;
        }
      }
    }
    const std::string name = xml_.substr(name_begin, name_stop - name_begin);
    element(name, name_stop, empty ? end - 1 : end, empty);
    if (!empty) {
      open_.push_back(name);
      if (open_.size() > kMaxXmlDepth) {
        fail(at, "nests XML elements more than " + std::to_string(kMaxXmlDepth) +
                     " deep; a URDF needs about 5 levels");
      }
    }
    return end + 1;
  }

  std::size_t end_tag(std::size_t at) {
    const std::size_t name_stop = name_end(at + 2);
    const std::size_t close = skip_space(name_stop);
    if (close < xml_.size() && xml_[close] == '>' && !open_.empty() &&
        xml_.compare(at + 2, name_stop - at - 2, open_.back()) == 0) {
      if (open_.size() == 2 && in_robot_ && open_.back() == "joint" && joint_open_) {
        joint_open_ = false;
        if (joint_.name_given && joint_.parent_given && joint_.child_given) {
          joints_.push_back({joint_.name, joint_.parent, joint_.child});
        }
      }
      if (open_.size() == 1) in_robot_ = false;
      open_.pop_back();
      return close + 1;
    }
    return past(at + 2, ">", at, "a tag");
  }

  // The value of attribute `wanted` in attributes [begin, end) of a start tag, as TinyXML reads
  // it (quoted, or unquoted up to white space, '/' or '>'); false if absent or unreadable.
  bool attribute(std::size_t begin, std::size_t end, const std::string& wanted,
                 std::string& value) const {
    std::size_t i = skip_space(begin);
    while (i < end && is_name_start(xml_[i])) {
      const std::size_t stop = name_end(i);
      const bool match = xml_.compare(i, stop - i, wanted) == 0;
      i = skip_space(stop);
      if (i >= end || xml_[i] != '=') return false;
      i = skip_space(i + 1);
      if (i >= end) return false;
      std::size_t value_begin = i, value_end;
      if (xml_[i] == '"' || xml_[i] == '\'') {
        value_begin = i + 1;
        value_end = std::string_view(xml_).substr(0, end).find(xml_[i], value_begin);
        if (value_end == std::string_view::npos) return false;
        i = value_end + 1;
      } else {
        while (i < end && !is_space(xml_[i]) && xml_[i] != '/' && xml_[i] != '>') ++i;
        value_end = i;
      }
      if (match) {
        value = xml_.substr(value_begin, value_end - value_begin);
        return true;
      }
      i = skip_space(i);
    }
    return false;
  }

  // urdfdom reads the first top-level <robot>, its <joint> children and their first <parent>
  // and <child>.
  void element(const std::string& name, std::size_t attributes_begin, std::size_t attributes_end,
               bool empty) {
    if (open_.empty()) {
      if (name == "robot" && !robot_seen_) {
        robot_seen_ = true;
        in_robot_ = !empty;
      }
      return;
    }
    if (!in_robot_) return;
    if (open_.size() == 1 && name == "joint") {
      joint_ = JointText();
      joint_.name_given = attribute(attributes_begin, attributes_end, "name", joint_.name);
      joint_open_ = !empty;
    } else if (open_.size() == 2 && joint_open_ && (name == "parent" || name == "child")) {
      const bool parent = name == "parent";
      bool& seen = parent ? joint_.parent_seen : joint_.child_seen;
      if (seen) return;
      seen = true;
      (parent ? joint_.parent_given : joint_.child_given) = attribute(
          attributes_begin, attributes_end, "link", parent ? joint_.parent : joint_.child);
    }
  }

  struct JointText {
    std::string name, parent, child;
    bool name_given = false, parent_seen = false, parent_given = false, child_seen = false,
         child_given = false;
  };

  const std::string& xml_;
  const std::string& source_;
  std::vector<std::string> open_;  // names of the open elements, outermost first
  bool robot_seen_ = false;
  bool in_robot_ = false;
  bool joint_open_ = false;
  JointText joint_;
  std::vector<TreeJoint> joints_;
};

// ---------------------------------------------------------------------------------------------
// Parsing. urdfdom reports what went wrong only through console_bridge's log (and in some cases,
// e.g. a mass of "nan", logs an error yet still returns a model). The errors are captured here so
// that they reach the exception message instead of stderr, and any logged error counts as a
// failure. console_bridge keeps one global handler, so parses are serialised.

class CapturingHandler : public console_bridge::OutputHandler {
 public:
  explicit CapturingHandler(console_bridge::OutputHandler* previous) : previous_(previous) {}

  void log(const std::string& text, console_bridge::LogLevel level, const char* filename,
           int line) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR) {
      errors_.push_back(text);
    } else if (previous_ != nullptr) {
      previous_->log(text, level, filename, line);  // warnings and below go where they went
    }
  }

  const std::vector<std::string>& errors() const { return errors_; }

 private:
  console_bridge::OutputHandler* previous_;
  std::vector<std::string> errors_;
};

std::mutex& parse_mutex() {
  static std::mutex mutex;
  return mutex;
}

urdf::ModelInterfaceSharedPtr parse(const std::string& xml, const std::string& source) {
  urdf::ModelInterfaceSharedPtr model;
  std::vector<std::string> errors;
  std::string exception_text;
  {
    const std::lock_guard<std::mutex> lock(parse_mutex());
    CapturingHandler handler(console_bridge::getOutputHandler());
    console_bridge::useOutputHandler(&handler);
    // Errors must reach the handler even if the application silenced console_bridge (a level
    // above ERROR); a lower level is kept, so what passes besides errors is what passed before.
    const console_bridge::LogLevel level = console_bridge::getLogLevel();
    if (level > console_bridge::CONSOLE_BRIDGE_LOG_ERROR) {
      console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_ERROR);
    }
    try {
      model = urdf::parseURDF(xml);
    } catch (const std::exception& exception) {
      exception_text = exception.what();
    }
    console_bridge::setLogLevel(level);
    console_bridge::restorePreviousOutputHandler();
    errors = handler.errors();
  }
  if (!exception_text.empty()) errors.push_back(exception_text);
  if (model != nullptr && errors.empty()) return model;

  std::ostringstream message;
  message << source << " is not a valid URDF";
  if (errors.empty()) {
    message << " (urdfdom gave no reason)";
  } else {
    message << ": urdfdom says: ";
    for (std::size_t i = 0; i < errors.size(); ++i) message << (i ? "; " : "") << errors[i];
  }
  throw Error(message.str());
}

// ---------------------------------------------------------------------------------------------
// Conversions.

Eigen::Isometry3d to_eigen(const urdf::Pose& pose) {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  // urdfdom stores the rpy of the file as a unit quaternion.
  const Eigen::Quaterniond rotation(pose.rotation.w, pose.rotation.x, pose.rotation.y,
                                    pose.rotation.z);
  transform.linear() = rotation.normalized().toRotationMatrix();
  return transform;
}

KDL::Vector to_kdl(const Eigen::Vector3d& v) {
  return KDL::Vector(v.x(), v.y(), v.z());
}

// `pose` as a transform; `what` ("joint 'j' has origin") names it if it is out of bounds.
Eigen::Isometry3d checked_pose(const urdf::Pose& pose, const std::string& what) {
  const Eigen::Vector3d xyz(pose.position.x, pose.position.y, pose.position.z);
  if (!(xyz.cwiseAbs().maxCoeff() <= kMaxDistance) || !xyz.allFinite()) {
    std::ostringstream message;
    message << what << " xyz = " << format_vector(xyz) << "; expected finite coordinates within +-"
            << kMaxDistance << " m";
    throw Error(message.str());
  }
  const Eigen::Isometry3d transform = to_eigen(pose);
  if (!transform.matrix().allFinite()) {
    throw Error(what + " with a rotation that is not finite; expected finite rpy angles");
  }
  return transform;
}

Eigen::Isometry3d checked_origin(const urdf::Joint& joint) {
  return checked_pose(joint.parent_to_joint_origin_transform,
                      "joint " + quoted(joint.name) + " has origin");
}

const char* joint_type_name(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE:
      return "revolute";
    case urdf::Joint::CONTINUOUS:
      return "continuous";
    case urdf::Joint::PRISMATIC:
      return "prismatic";
    case urdf::Joint::FLOATING:
      return "floating";
    case urdf::Joint::PLANAR:
      return "planar";
    case urdf::Joint::FIXED:
      return "fixed";
    default:
      return "of unknown type";
  }
}

// Mass, centre of mass and rotational inertia about the centre of mass, all in one link's frame.
struct MassProperties {
  double mass = 0.0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
};

// The same body seen from a frame in which the current one is at `T`.
MassProperties transformed(const Eigen::Isometry3d& T, const MassProperties& body) {
  MassProperties result;
  result.mass = body.mass;
  result.com = T * body.com;
  result.inertia = T.linear() * body.inertia * T.linear().transpose();
  return result;
}

// Two rigidly joined bodies as one (parallel-axis theorem about the joint centre of mass).
MassProperties combined(const MassProperties& a, const MassProperties& b) {
  MassProperties result;
  result.mass = a.mass + b.mass;
  if (result.mass > 0.0) result.com = (a.mass * a.com + b.mass * b.com) / result.mass;
  const auto shifted = [&result](const MassProperties& body) {
    const Eigen::Vector3d d = body.com - result.com;
    return Eigen::Matrix3d(body.inertia +
                           body.mass *
                               (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose()));
  };
  result.inertia = shifted(a) + shifted(b);
  return result;
}

// A link's own inertial, converted from the URDF inertial frame to the link frame: the centre of
// mass is the inertial origin, the tensor (given in the axes of the inertial frame) is rotated
// into the link axes, R I R^T.
MassProperties link_mass_properties(const urdf::Link& link) {
  MassProperties body;
  if (!link.inertial) return body;
  const urdf::Inertial& inertial = *link.inertial;
  if (!(inertial.mass >= 0.0 && inertial.mass <= kMaxMass)) {
    std::ostringstream message;
    message << "link " << quoted(link.name) << " has mass = " << inertial.mass
            << " kg; expected a finite value >= 0 kg and <= " << kMaxMass << " kg";
    throw Error(message.str());
  }
  const std::pair<const char*, double> entries[] = {{"ixx", inertial.ixx}, {"ixy", inertial.ixy},
                                                    {"ixz", inertial.ixz}, {"iyy", inertial.iyy},
                                                    {"iyz", inertial.iyz}, {"izz", inertial.izz}};
  for (const auto& [name, value] : entries) {
    if (!(std::abs(value) <= kMaxInertia)) {
      std::ostringstream message;
      message << "link " << quoted(link.name) << " has inertia " << name << " = " << value
              << " kg m^2; expected finite entries within +-" << kMaxInertia << " kg m^2";
      throw Error(message.str());
    }
  }
  Eigen::Matrix3d tensor;
  tensor << inertial.ixx, inertial.ixy, inertial.ixz,  //
      inertial.ixy, inertial.iyy, inertial.iyz,        //
      inertial.ixz, inertial.iyz, inertial.izz;
  // A tensor with a negative principal moment would make the mass matrix indefinite. Rounding in
  // a file may leave a zero moment slightly negative, hence the tolerance relative to the trace.
  const double smallest =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(tensor, Eigen::EigenvaluesOnly)
          .eigenvalues()
          .minCoeff();
  if (smallest < -1e-9 * std::max(tensor.trace(), 1e-300)) {
    std::ostringstream message;
    message << "link " << quoted(link.name) << " has an inertia tensor that is not positive "
            << "semi-definite (smallest principal moment " << smallest << " kg m^2; expected >= 0)";
    throw Error(message.str());
  }
  const Eigen::Isometry3d T_link_inertial =
      checked_pose(inertial.origin, "link " + quoted(link.name) + " has inertial origin");
  body.mass = inertial.mass;
  body.com = T_link_inertial.translation();
  body.inertia = T_link_inertial.linear() * tensor * T_link_inertial.linear().transpose();
  return body;
}

// `link` and every link attached to it through fixed joints, except the branch of `on_chain`.
// A file may attach any number of links in a row, so the sub-tree is walked with a worklist, not
// by recursion.
MassProperties rigid_body_of(const urdf::Link& link, const urdf::Link* on_chain) {
  struct Attached {
    const urdf::Link* link;
    Eigen::Isometry3d T_top_link;  // its frame in the frame of `link`
  };
  MassProperties body = link_mass_properties(link);
  std::vector<Attached> pending{{&link, Eigen::Isometry3d::Identity()}};
  while (!pending.empty()) {
    const Attached parent = pending.back();
    pending.pop_back();
    if (parent.link != &link) {
      body = combined(body, transformed(parent.T_top_link, link_mass_properties(*parent.link)));
    }
    for (const urdf::LinkSharedPtr& child : parent.link->child_links) {
      if (!child || child.get() == on_chain) continue;
      const urdf::JointSharedPtr& joint = child->parent_joint;
      if (!joint || joint->type != urdf::Joint::FIXED) continue;
      pending.push_back({child.get(), parent.T_top_link * checked_origin(*joint)});
    }
  }
  return body;
}

KDL::RigidBodyInertia to_kdl(const MassProperties& body) {
  const Eigen::Matrix3d& i = body.inertia;
  // KDL wants the rotational inertia about the centre of mass, in the link frame's axes.
  return KDL::RigidBodyInertia(
      body.mass, to_kdl(body.com),
      KDL::RotationalInertia(i(0, 0), i(1, 1), i(2, 2), i(0, 1), i(0, 2), i(1, 2)));
}

std::string describe_links(const urdf::ModelInterface& model) {
  // urdfdom keeps links in a std::map, so they come sorted by name.
  constexpr std::size_t kShown = 12;
  std::ostringstream text;
  std::size_t shown = 0;
  for (const auto& entry : model.links_) {
    if (shown == kShown) break;
    text << (shown ? ", " : "") << entry.first;
    ++shown;
  }
  if (model.links_.size() > kShown) text << ", ... (" << model.links_.size() << " in all)";
  return text.str();
}

const urdf::Link& find_link(const urdf::ModelInterface& model, const std::string& name,
                            const char* role, const std::string& source) {
  const auto found = model.links_.find(name);
  if (found == model.links_.end() || !found->second) {
    throw Error(std::string(role) + " " + quoted(name) + " is not a link of " + source +
                " (robot " + quoted(model.name_) + "; its links are: " + describe_links(model) +
                ")");
  }
  return *found->second;
}

// The walks towards the root below end because check_tree() ruled out loops; the bound on the
// steps is a second line of defence against a walk without end.
bool is_ancestor(const urdf::Link& ancestor, const urdf::Link& link, std::size_t links) {
  std::size_t steps = 0;
  for (urdf::LinkConstSharedPtr up = link.getParent(); up && steps <= links;
       up = up->getParent(), ++steps) {
    if (up.get() == &ancestor) return true;
  }
  return false;
}

std::string path_to_root(const urdf::Link& link, std::size_t links) {
  std::string text = link.name;
  std::size_t steps = 0;
  for (urdf::LinkConstSharedPtr up = link.getParent(); up && steps <= links;
       up = up->getParent(), ++steps) {
    text += " <- " + up->name;
  }
  return text;
}

KDL::Joint to_kdl_joint(const urdf::Joint& joint, const Eigen::Isometry3d& T_parent_joint) {
  const Eigen::Vector3d axis(joint.axis.x, joint.axis.y, joint.axis.z);
  // Scaled by its largest component first, so that the norm of a large axis does not overflow
  // (the norm of (1e200, 0, 0) is 1e200, not sqrt(inf)).
  const double largest = axis.allFinite() ? axis.cwiseAbs().maxCoeff() : kInfinity;
  const Eigen::Vector3d scaled = largest > 0.0 ? Eigen::Vector3d(axis / largest) : axis;
  const double norm = axis.allFinite() ? largest * scaled.norm() : kInfinity;
  if (!(norm >= kMinAxisNorm && norm <= kMaxAxisNorm)) {
    std::ostringstream message;
    message << "joint " << quoted(joint.name) << " has axis = " << format_vector(axis)
            << " of norm " << norm << "; expected a finite non-zero direction: finite components "
            << "and a norm in [" << kMinAxisNorm << ", " << kMaxAxisNorm << "]";
    throw Error(message.str());
  }
  // As kdl_parser: the joint sits at the joint origin, its axis rotated into the parent frame.
  const KDL::Vector origin = to_kdl(T_parent_joint.translation());
  const KDL::Vector axis_parent = to_kdl(T_parent_joint.linear() * scaled.normalized());
  const KDL::Joint::JointType kdl_type =
      joint.type == urdf::Joint::PRISMATIC ? KDL::Joint::TransAxis : KDL::Joint::RotAxis;
  return KDL::Joint(joint.name, origin, axis_parent, kdl_type);
}

void read_limits(const urdf::Joint& joint, JointType type, int index, JointLimits& limits) {
  const auto fail = [&joint](const std::string& what) {
    throw Error("joint " + quoted(joint.name) + " has " + what);
  };
  double lower = -kInfinity, upper = kInfinity, velocity = kInfinity, effort = kInfinity;
  if (joint.limits) {
    const urdf::JointLimits& given = *joint.limits;
    if (type != JointType::continuous) {
      lower = given.lower;
      upper = given.upper;
      // A prismatic joint's travel is a distance like any other.
      const double bound = type == JointType::prismatic ? kMaxDistance : kInfinity;
      if (!std::isfinite(lower) || !std::isfinite(upper) || lower > upper ||
          std::abs(lower) > bound || std::abs(upper) > bound) {
        std::ostringstream what;
        what << "position limits [" << lower << ", " << upper
             << "]; expected finite lower <= upper";
        if (type == JointType::prismatic) what << " within +-" << kMaxDistance << " m";
        fail(what.str());
      }
    }
    velocity = given.velocity;
    effort = given.effort;
    if (std::isnan(velocity) || velocity < 0.0) {
      std::ostringstream what;
      what << "velocity limit = " << velocity << "; expected a value >= 0";
      fail(what.str());
    }
    if (std::isnan(effort) || effort < 0.0) {
      std::ostringstream what;
      what << "effort limit = " << effort << "; expected a value >= 0";
      fail(what.str());
    }
  }
  limits.position_lower[index] = lower;
  limits.position_upper[index] = upper;
  limits.velocity[index] = velocity;
  limits.effort[index] = effort;
}

// urdfdom's model, released without leaks: its links own their children, so a loop of links
// (which check_tree() rejects after urdfdom built it) would keep itself alive.
struct ModelOwner {
  explicit ModelOwner(urdf::ModelInterfaceSharedPtr parsed) : model(std::move(parsed)) {}
  ModelOwner(const ModelOwner&) = delete;
  ModelOwner& operator=(const ModelOwner&) = delete;
  ~ModelOwner() {
    for (const auto& entry : model->links_) {
      if (!entry.second) continue;
      entry.second->child_links.clear();
      entry.second->child_joints.clear();
    }
  }
  urdf::ModelInterfaceSharedPtr model;
};

}  // namespace

KDL::Frame to_kdl_frame(const Eigen::Isometry3d& transform) {
  const Eigen::Matrix3d& r = transform.linear();
  return KDL::Frame(KDL::Rotation(r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0),
                                  r(2, 1), r(2, 2)),
                    to_kdl(transform.translation()));
}

std::string format_vector(const Eigen::Vector3d& v) {
  std::ostringstream text;
  text << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return text.str();
}

UrdfChain urdf_to_kdl_chain(const std::string& xml, const std::string& source,
                            const std::string& base_link, const std::string& tip_link) {
  // On the text first: neither TinyXML's recursion nor urdfdom's leak on a loop may be reached.
  check_tree(XmlPrescan(xml, source).run(), source);
  const ModelOwner owner(parse(xml, source));
  const urdf::ModelInterface& model = *owner.model;
  // Again on urdfdom's model, which decoded the names (and is what the walks below follow).
  std::vector<TreeJoint> joints;
  joints.reserve(model.joints_.size());
  for (const auto& entry : model.joints_) {
    if (entry.second) {
      joints.push_back(
          {entry.second->name, entry.second->parent_link_name, entry.second->child_link_name});
    }
  }
  check_tree(joints, source);
  const std::size_t link_count = model.links_.size();
  const urdf::Link& base = find_link(model, base_link, "base link", source);
  const urdf::Link& tip = find_link(model, tip_link, "tip link", source);

  if (&base == &tip) {
    throw Error("tip link " + quoted(tip_link) + " is the base link; the chain from base to tip " +
                "must contain at least one movable joint");
  }
  if (!is_ancestor(base, tip, link_count)) {
    if (is_ancestor(tip, base, link_count)) {
      throw Error("tip link " + quoted(tip_link) + " is above base link " + quoted(base_link) +
                  " in the URDF tree of " + source +
                  "; expected the tip below the base (swap them?)");
    }
    throw Error("tip link " + quoted(tip_link) + " is not below base link " + quoted(base_link) +
                " in the URDF tree of " + source +
                " (path from the tip to the root: " + path_to_root(tip, link_count) + ")");
  }

  // Links from just below the base down to the tip.
  std::vector<const urdf::Link*> links;
  for (const urdf::Link* link = &tip; link != &base; link = link->getParent().get()) {
    links.push_back(link);
  }
  std::reverse(links.begin(), links.end());

  UrdfChain result;
  result.robot_name = model.name_;
  std::vector<const urdf::Joint*> movable;
  for (const urdf::Link* link : links) {
    const urdf::Joint& joint = *link->parent_joint;
    switch (joint.type) {
      case urdf::Joint::REVOLUTE:
      case urdf::Joint::CONTINUOUS:
      case urdf::Joint::PRISMATIC:
      case urdf::Joint::FIXED:
        break;
      default:
        throw Error("joint " + quoted(joint.name) + " between " + quoted(joint.parent_link_name) +
                    " and " + quoted(joint.child_link_name) + " is " + joint_type_name(joint.type) +
                    "; the chain from " + quoted(base_link) + " to " + quoted(tip_link) +
                    " may contain only revolute, continuous, prismatic and fixed joints");
    }
    if (joint.mimic && joint.type != urdf::Joint::FIXED) {
      throw Error("joint " + quoted(joint.name) + " mimics joint " +
                  quoted(joint.mimic->joint_name) +
                  "; mimic joints are not supported in the chain");
    }
    if (joint.type != urdf::Joint::FIXED) movable.push_back(&joint);
  }
  const int n = static_cast<int>(movable.size());
  if (n == 0) {
    throw Error("the chain from " + quoted(base_link) + " to " + quoted(tip_link) + " of " +
                source + " has no movable joint; expected at least 1");
  }
  if (n > kMaxJoints) {
    throw Error("the chain from " + quoted(base_link) + " to " + quoted(tip_link) + " has " +
                std::to_string(n) + " movable joints; at most kMaxJoints = " +
                std::to_string(kMaxJoints) + " are supported");
  }

  result.limits.position_lower.resize(n);
  result.limits.position_upper.resize(n);
  result.limits.velocity.resize(n);
  result.limits.effort.resize(n);
  for (std::size_t i = 0; i < links.size(); ++i) {
    const urdf::Link& link = *links[i];
    const urdf::Joint& joint = *link.parent_joint;
    const Eigen::Isometry3d T_parent_joint = checked_origin(joint);
    KDL::Joint kdl_joint(joint.name, KDL::Joint::None);
    if (joint.type != urdf::Joint::FIXED) {
      const JointType type = joint.type == urdf::Joint::PRISMATIC    ? JointType::prismatic
                             : joint.type == urdf::Joint::CONTINUOUS ? JointType::continuous
                                                                     : JointType::revolute;
      read_limits(joint, type, static_cast<int>(result.joint_names.size()), result.limits);
      result.joint_names.push_back(joint.name);
      result.joint_types.push_back(type);
      kdl_joint = to_kdl_joint(joint, T_parent_joint);
    }
    const urdf::Link* next_on_chain = i + 1 < links.size() ? links[i + 1] : nullptr;
    const MassProperties body = rigid_body_of(link, next_on_chain);
    result.moving_mass += body.mass;
    // The segment's tip frame is the joint origin (at q = 0), i.e. the child link's frame.
    result.chain.addSegment(
        KDL::Segment(link.name, kdl_joint, to_kdl_frame(T_parent_joint), to_kdl(body)));
  }
  return result;
}

}  // namespace cartesian_impedance::detail
