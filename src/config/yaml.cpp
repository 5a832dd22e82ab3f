#include "cartesian_impedance/config/yaml.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <locale>
#include <optional>
#include <sstream>
#include <unordered_map>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/files.hpp"
#include "cartesian_impedance/core/parameter_tree.hpp"

// The YAML adapter of the parameter decoder (parameter_tree.hpp): YAML text -> ParameterValue
// tree with line numbers, then decode_parameters(). Only what YAML itself brings is checked here:
// malformed text, a second document, keys that are not names, duplicate and merge keys, and which
// scalars are strings (quoted, tagged, block) rather than numbers or switches.

namespace cartesian_impedance {
namespace {

std::string location(std::string_view source, const YAML::Mark& mark) {
  std::string text(source);
  if (mark.line >= 0) text += ":" + std::to_string(mark.line + 1);
  return text;
}

[[noreturn]] void fail(std::string_view source, const YAML::Mark& mark, const std::string& what) {
  throw Error(with_location(location(source, mark), what));
}

// "!!str" for yaml-cpp's "tag:yaml.org,2002:str".
std::string tag_text(const std::string& tag) {
  const std::string standard = "tag:yaml.org,2002:";
  return tag.compare(0, standard.size(), standard) == 0 ? "!!" + tag.substr(standard.size()) : tag;
}

// True if `text` is a decimal number too large for a double, e.g. 1e400, which yaml-cpp does not
// convert: such a value is out of range, not a typo, and is reported with the range.
bool overflows(const std::string& text) {
  std::istringstream stream(text);
  stream.imbue(std::locale::classic());
  double value = 0.0;
  stream >> value;
  // On overflow the stream fails and holds the largest double ([facet.num.get.virtuals]); eof
  // means the number was the whole text.
  return stream.fail() && stream.eof() && std::abs(value) == std::numeric_limits<double>::max();
}

// Converts yaml-cpp nodes into the decoder's values, inside the bounds every source keeps
// (ParameterTreeGuard): an alias of a list or map inside itself, nesting without end and aliases
// that repeat a list or map until the text names millions of values are refused by path.
class Converter {
 public:
  explicit Converter(std::string_view source) : source_(source) {}

  // `node` at `path`; `reference` places the guard's messages where the node is used (a map
  // member's key) rather than where it is written, which for an alias is its anchor.
  ParameterValue convert(const YAML::Node& node, const std::string& path,
                         const std::string& reference = {}) {
    std::string where = location(source_, node.Mark());
    const std::string& used = reference.empty() ? where : reference;
    guard_.count(path, used);
    if (node.IsSequence() || node.IsMap()) {
      // yaml-cpp shows a node's identity only through its storage: an alias is its anchor's node
      // itself, so it has the same scalar storage (empty for a list or map, but one object).
      const ParameterTreeGuard::Level level = guard_.enter(&node.Scalar(), path, used);
      if (node.IsMap()) return ParameterValue::map(members(node, path), where);
      ParameterList items;
      for (const YAML::Node& item : node) {
        items.push_back(convert(item, path + "[" + std::to_string(items.size()) + "]"));
      }
      return ParameterValue::list(std::move(items), where);
    }
    if (node.IsNull()) {
      ParameterValue empty;
      empty.location = std::move(where);
      return empty;
    }
    return scalar(node, where);
  }

 private:
  // yaml-cpp converts the text of any scalar, but in YAML a quoted scalar (or a block scalar, both
  // tagged "!") is a string, and a tag says what a scalar is: only a plain, untagged scalar ("?")
  // may be read as a number or a switch.
  static ParameterValue scalar(const YAML::Node& node, const std::string& where) {
    const std::string& text = node.Scalar();
    if (node.Tag() == "?") {
      double number = 0.0;
      bool flag = false;
      if (YAML::convert<double>::decode(node, number)) return ParameterValue::number(number, where);
      if (overflows(text)) return ParameterValue::too_large(text, text[0] == '-', where);
      if (YAML::convert<bool>::decode(node, flag)) return ParameterValue::boolean(flag, where);
      return ParameterValue::string(text, where);
    }
    ParameterValue value = ParameterValue::string(text, where);
    value.hint = node.Tag() == "!"
                     ? "it is quoted or a block scalar, which makes it a string in YAML: write it "
                       "without quotes"
                     : "it has the tag " + tag_text(node.Tag()) + ": write it without a tag";
    return value;
  }

  // The members of map `node` at `path`. yaml-cpp keeps every entry of a map, so a key given twice
  // would silently take the value read last; a key that is not a name (a list, a map, empty) has
  // no path at all; and a merge key would silently copy values.
  ParameterMap members(const YAML::Node& node, const std::string& path) {
    const std::string in = path.empty() ? "" : "in " + path + ": ";
    std::unordered_map<std::string, int> lines;
    ParameterMap result;
    for (const auto& entry : node) {
      const YAML::Node& key = entry.first;
      if (!key.IsScalar()) {
        // An empty key has no position of its own in yaml-cpp; its value or map has.
        YAML::Mark mark = key.Mark();
        if (mark.line < 0) mark = entry.second.Mark();
        if (mark.line < 0) mark = node.Mark();
        fail(source_, mark,
             in + "a key is " +
                 (key.IsSequence() ? "a list"
                  : key.IsMap()    ? "a map"
                                   : "empty") +
                 "; expected a parameter name");
      }
      const std::string child = path.empty() ? key.Scalar() : path + "." + key.Scalar();
      const auto [first, inserted] = lines.emplace(key.Scalar(), key.Mark().line + 1);
      if (!inserted) {
        fail(source_, key.Mark(),
             "'" + child + "' is given twice, on lines " + std::to_string(first->second) + " and " +
                 std::to_string(key.Mark().line + 1) + "; expected each key once");
      }
    }
    for (const auto& entry : node) {
      const YAML::Node& key = entry.first;
      const std::string child = path.empty() ? key.Scalar() : path + "." + key.Scalar();
      if (key.Scalar() == "<<" && key.Tag() == "?") {
        fail(source_, key.Mark(),
             "'" + child +
                 "' is a merge key, and merge keys are not supported; write the values out");
      }
      const std::string key_location = location(source_, key.Mark());
      guard_.count(child, key_location);
      ParameterValue value = convert(entry.second, child, key_location);
      if (value.location == source_ || value.is(ParameterValue::Kind::empty)) {
        value.location = location(source_, key.Mark());  // an empty value has no line of its own
      }
      result.push_back({key.Scalar(), std::move(value), location(source_, key.Mark())});
    }
    return result;
  }

  std::string_view source_;
  ParameterTreeGuard guard_;
};

void emit(YAML::Emitter& out, const ParameterValue& value) {
  switch (value.kind()) {
    case ParameterValue::Kind::empty:
      out << YAML::Null;
      break;
    case ParameterValue::Kind::number:
      // The shortest text that reads back as the same double: what the user wrote (0.2), not
      // yaml-cpp's 17 digits (0.20000000000000001). Infinities keep YAML's own spelling (.inf).
      if (std::isfinite(value.as_number())) {
        out << format_exact(value.as_number());
      } else {
        out << value.as_number();
      }
      break;
    case ParameterValue::Kind::boolean:
      out << value.as_boolean();
      break;
    case ParameterValue::Kind::string:
      out << value.as_string();
      break;
    case ParameterValue::Kind::list:
      out << YAML::Flow << YAML::BeginSeq;
      for (const ParameterValue& item : value.as_list()) emit(out, item);
      out << YAML::EndSeq;
      break;
    case ParameterValue::Kind::map:
      out << YAML::BeginMap;
      for (const ParameterMember& member : value.as_map()) {
        out << YAML::Key << member.key << YAML::Value;
        emit(out, member.value);
      }
      out << YAML::EndMap;
      break;
  }
}

// Where each document begins, and where its content (its first node) begins. Counts the nodes
// as the parser reads them and stops it at one more than any tree may hold (keys and aliases are
// nodes too, and the converter counts each of them at least once): the text is refused before
// yaml-cpp builds its own tree of it, which takes hundreds of bytes per node (a list of millions
// of numbers in a 50 MB text took about a minute and 8 to 12 GB before it was refused).
class DocumentStarts final : public YAML::EventHandler {
 public:
  explicit DocumentStarts(std::string_view source) : source_(source) {}
  std::vector<YAML::Mark> starts, contents;
  void OnDocumentStart(const YAML::Mark& mark) override {
    starts.push_back(mark);
    contents.push_back(mark);
    first_node_ = true;
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t) override { node(mark); }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override { node(mark); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                const std::string&) override {
    node(mark);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {
    node(mark);
  }
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {
    node(mark);
  }
  void OnMapEnd() override {}

 private:
  void node(const YAML::Mark& mark) {
    if (first_node_) contents.back() = mark;
    first_node_ = false;
    if (++nodes_ > ParameterTreeGuard::kMaxValues) {
      throw ParameterError(
          ParameterError::Reason::oversized,
          with_location(location(source_, mark),
                        "more than " + std::to_string(ParameterTreeGuard::kMaxValues) +
                            " values; a parameter set holds a few hundred"));
    }
  }
  std::string_view source_;
  bool first_node_ = false;
  std::size_t nodes_ = 0;
};

// The one document of the text (none if the text has none). A second document is reported rather
// than silently dropped (YAML::Load reads the first only). YAML::LoadAll is not used: yaml-cpp
// 0.7 never ends on a ',' after a top-level scalar or flow collection (or at the very start): it
// takes the ',' for the start of an empty document without consuming it, again and again, until
// memory runs out. So at most two documents are parsed here, the second only to report it.
std::optional<YAML::Node> the_document(const std::string& yaml, std::string_view source) {
  std::istringstream stream(yaml);
  YAML::Parser parser(stream);
  DocumentStarts starts(source);
  for (int document = 0; document < 2 && parser.HandleNextDocument(starts); ++document) {
  }
  if (starts.starts.size() > 1) {
    const YAML::Mark& start = starts.starts[1];
    // yaml-cpp counts a byte-order mark as no position.
    std::size_t at = static_cast<std::size_t>(start.pos);
    if (yaml.compare(at, 3, "\xef\xbb\xbf") == 0) at += 3;
    if (at < yaml.size() && yaml[at] == ',') {
      fail(source, start,
           "malformed YAML: ',' outside a list or map (column " + std::to_string(start.column + 1) +
               ")");
    }
    // An empty document has the position of the end of the text, which would mislead.
    const YAML::Mark& content = starts.contents[1];
    const bool at_end = static_cast<std::size_t>(content.pos) >= yaml.size();
    fail(source, at_end ? YAML::Mark::null_mark() : content,
         "a second YAML document (after '---'); a parameter file holds only one document");
  }
  if (starts.starts.empty()) return std::nullopt;
  return YAML::Load(yaml);
}

}  // namespace

ParameterValue parameter_tree_from_yaml(const std::string& yaml, std::string_view source) {
  std::optional<YAML::Node> document;
  try {
    document = the_document(yaml, source);
  } catch (const YAML::DeepRecursion& error) {
    // yaml-cpp's parser recurses once per level and stops at a bound of its own, before the
    // converter's (ParameterTreeGuard::kMaxDepth) is reached on the levels it built.
    fail(source, error.mark,
         "the YAML is nested too deeply (" + std::to_string(error.depth()) +
             " levels); parameters are nested at most " + std::to_string(parameter_table_depth()) +
             " levels deep, with a list of numbers below");
  } catch (const YAML::Exception& error) {
    std::string column;
    if (!error.mark.is_null()) column = " (column " + std::to_string(error.mark.column + 1) + ")";
    fail(source, error.mark, "malformed YAML: " + error.msg + column);
  }
  ParameterValue tree;
  try {
    if (document) tree = Converter(source).convert(*document, "");
  } catch (const YAML::Exception& error) {
    // Reading only asks for what it checked is there; should yaml-cpp still object, it is an
    // Error like any other.
    fail(source, error.mark, "cannot read the YAML: " + error.msg);
  }
  return tree;
}

Parameters parameters_from_yaml(const std::string& yaml, std::string_view source,
                                const Parameters& defaults) {
  return decode_parameters(parameter_tree_from_yaml(yaml, source), defaults, source);
}

Parameters load_parameters(const std::string& path, const Parameters& defaults) {
  return parameters_from_yaml(read_regular_file(path, "parameter file"), path, defaults);
}

void save_parameters(const std::string& path, const Parameters& parameters) {
  std::ofstream file(path);
  file << parameters_to_yaml(parameters);
  file.close();
  if (!file) throw Error("cannot write parameter file '" + path + "'");
}

std::string parameters_to_yaml(const Parameters& parameters) {
  YAML::Emitter out;
  emit(out, encode_parameters(parameters));
  return std::string(out.c_str()) + "\n";
}

}  // namespace cartesian_impedance
