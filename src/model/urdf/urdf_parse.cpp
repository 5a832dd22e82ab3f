// Reading a URDF document (urdf_parse.hpp): the checks on its text before urdfdom parses it, the
// tree check, and urdfdom's parse with its errors captured.

#include "urdf_parse.hpp"

#include <console_bridge/console.h>

#include <algorithm>
#include <cctype>
#include <mutex>
#include <sstream>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::detail {
namespace {

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

// 1-based line of byte `position` of `text`, for messages.
std::size_t line_at(const std::string& text, std::size_t position) {
  return 1 + static_cast<std::size_t>(std::count(
                 text.begin(), text.begin() + static_cast<std::ptrdiff_t>(position), '\n'));
}

}  // namespace

std::string quoted(const std::string& name) {
  return "'" + name + "'";
}

// ---------------------------------------------------------------------------------------------
// The tree. urdfdom links every joint's child to its parent without checking that the joints
// form a tree: a link with two parent joints keeps one of them, and a loop of links (a joint from
// a link to itself is the shortest) makes every walk towards the root endless and leaves
// urdfdom's links owning each other. The joints are therefore checked, on the text before
// urdfdom builds anything and again on urdfdom's model.

namespace {

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

}  // namespace

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

namespace {

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

}  // namespace

std::vector<TreeJoint> prescan_urdf(const std::string& xml, const std::string& source) {
  return XmlPrescan(xml, source).run();
}

// ---------------------------------------------------------------------------------------------
// Parsing. urdfdom reports what went wrong only through console_bridge's log (and in some cases,
// e.g. a mass of "nan", logs an error yet still returns a model). The errors are captured here so
// that they reach the exception message instead of stderr, and any logged error counts as a
// failure. console_bridge keeps one global handler, so parses are serialised.

namespace {

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

}  // namespace

urdf::ModelInterfaceSharedPtr parse_urdf(const std::string& xml, const std::string& source) {
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

}  // namespace cartesian_impedance::detail
