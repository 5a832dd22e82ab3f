#pragma once
// Mutation fuzzing for the loaders' tests: deterministic variants of real input files (byte
// flips, deletions, duplicated, swapped and spliced lines, numbers replaced by extreme values,
// deep nesting, truncation), and the bookkeeping of a fuzz run. Header-only, used by
// fuzz_urdf_test.cpp and fuzz_yaml_test.cpp.

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace fuzz {

/// A piece of a text: offset and length.
using Span = std::pair<std::size_t, std::size_t>;

/// What a mutator knows of the format beyond bytes.
struct Format {
  std::vector<std::string> extremes;  ///< replacements for numbers: "nan", "1e308", ...
  std::vector<std::string> tokens;    ///< syntax to drop in anywhere: "<a>", "---", ...
  /// Nesting: `count` levels opened (and perhaps closed) as one piece of text.
  std::function<std::string(std::size_t count, std::mt19937& random)> nest;
  /// The self-contained pieces of a text that may be duplicated, removed, swapped or spliced
  /// (XML elements, YAML lines and blocks), so that most variants stay well-formed and reach the
  /// loader's checks rather than the parser's.
  std::function<std::vector<Span>(const std::string& text)> units;
};

/// Lines, and each line with the more indented lines below it (a YAML block).
inline std::vector<Span> line_blocks(const std::string& text) {
  std::vector<Span> lines;
  for (std::size_t begin = 0; begin < text.size();) {
    std::size_t end = text.find('\n', begin);
    end = end == std::string::npos ? text.size() : end + 1;
    lines.emplace_back(begin, end - begin);
    begin = end;
  }
  const auto indent = [&text](const Span& line) {
    std::size_t i = line.first;
    while (i < line.first + line.second && text[i] == ' ') ++i;
    return i - line.first;
  };
  std::vector<Span> units = lines;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::size_t last = i;
    while (last + 1 < lines.size() && indent(lines[last + 1]) > indent(lines[i])) ++last;
    if (last > i) {
      units.emplace_back(lines[i].first, lines[last].first + lines[last].second - lines[i].first);
    }
  }
  return units;
}

/// Elements, from start tag to end tag (or empty-element tag), found with a simple reading that
/// tolerates broken text (which mutations make).
inline std::vector<Span> xml_elements(const std::string& text) {
  std::vector<Span> elements;
  std::vector<std::pair<std::string, std::size_t>> open;
  for (std::size_t at = text.find('<'); at != std::string::npos; at = text.find('<', at)) {
    if (text.compare(at, 4, "<!--") == 0) {
      at = text.find("-->", at);
      if (at == std::string::npos) break;
      continue;
    }
    const std::size_t close = text.find('>', at);
    if (close == std::string::npos) break;
    const std::size_t tag = at;
    at = close;  // each byte is looked at once: mutations make long texts
    if (text[tag + 1] == '?' || text[tag + 1] == '!') continue;
    std::size_t name_end = tag + 1 + (text[tag + 1] == '/');
    while (name_end < close && text[name_end] != ' ' && text[name_end] != '/' &&
           text[name_end] != '\n') {
      ++name_end;
    }
    const std::size_t name_begin = tag + 1 + (text[tag + 1] == '/');
    const std::string name = text.substr(name_begin, name_end - name_begin);
    if (text[tag + 1] == '/') {
      if (!open.empty() && open.back().first == name) {
        elements.emplace_back(open.back().second, close + 1 - open.back().second);
        open.pop_back();
      }
    } else if (text[close - 1] == '/') {
      elements.emplace_back(tag, close + 1 - tag);
    } else {
      open.emplace_back(name, tag);
    }
  }
  return elements;
}

class Mutator {
 public:
  Mutator(std::vector<std::string> seeds, Format format, std::uint32_t seed)
      : seeds_(std::move(seeds)), format_(std::move(format)), random_(seed) {}

  /// A variant of seeds()[index]: 1 to 4 mutations, each drawn at random.
  std::string next(std::size_t index) {
    std::string text = seeds_[index];
    const int mutations = uniform(1, 4);
    for (int i = 0; i < mutations; ++i) text = mutate(std::move(text));
    return text;
  }

  const std::vector<std::string>& seeds() const { return seeds_; }
  std::mt19937& random() { return random_; }

 private:
  int uniform(int low, int high) { return std::uniform_int_distribution<int>(low, high)(random_); }
  std::size_t position(const std::string& text) {
    return std::uniform_int_distribution<std::size_t>(0, text.size())(random_);
  }
  template <typename T>
  const T& pick(const std::vector<T>& items) {
    return items[std::uniform_int_distribution<std::size_t>(0, items.size() - 1)(random_)];
  }

  // Numbers as they are written in both formats: a digit, or '-', '+' or '.' before a digit,
  // and what follows of [0-9.eE+-].
  static std::vector<std::pair<std::size_t, std::size_t>> numbers(const std::string& text) {
    std::vector<std::pair<std::size_t, std::size_t>> found;
    const auto digit = [](char c) { return c >= '0' && c <= '9'; };
    for (std::size_t i = 0; i < text.size();) {
      const bool starts = digit(text[i]) || ((text[i] == '-' || text[i] == '+' || text[i] == '.') &&
                                             i + 1 < text.size() && digit(text[i + 1]));
      if (!starts || (i > 0 && (std::isalnum(static_cast<unsigned char>(text[i - 1])) ||
                                text[i - 1] == '_'))) {
        ++i;
        continue;
      }
      std::size_t end = i + 1;
      while (end < text.size() && (digit(text[end]) || text[end] == '.' || text[end] == 'e' ||
                                   text[end] == 'E' || text[end] == '-' || text[end] == '+')) {
        ++end;
      }
      found.emplace_back(i, end - i);
      i = end;
    }
    return found;
  }

  // Words: runs of letters, digits and '_', e.g. link names and keys.
  static std::vector<std::pair<std::size_t, std::size_t>> words(const std::string& text) {
    std::vector<std::pair<std::size_t, std::size_t>> found;
    const auto word = [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    };
    for (std::size_t i = 0; i < text.size();) {
      if (!word(text[i])) {
        ++i;
        continue;
      }
      std::size_t end = i;
      while (end < text.size() && word(text[end])) ++end;
      found.emplace_back(i, end - i);
      i = end;
    }
    return found;
  }

  std::string mutate(std::string text) {
    // Weights: the sharp cases (numbers, names, structure) more often than bytes.
    static const std::vector<double> kWeights{
        2, 1, 1,  // bytes: set, bit, delete
        3, 2, 2,  // units: duplicate, remove or swap, splice from another seed
        5,        // a number made extreme
        2,        // a word replaced by another
        1, 1, 1   // nesting, truncation, syntax
    };
    std::discrete_distribution<int> kind(kWeights.begin(), kWeights.end());
    switch (kind(random_)) {
      case 0:  // any byte, NUL and invalid UTF-8 included
        if (!text.empty()) text[position(text) % text.size()] = static_cast<char>(uniform(0, 255));
        break;
      case 1:  // one bit
        if (!text.empty()) {
          text[position(text) % text.size()] ^= static_cast<char>(1 << uniform(0, 7));
        }
        break;
      case 2:  // a few bytes gone
        text.erase(position(text), static_cast<std::size_t>(uniform(1, 32)));
        break;
      case 3: {  // a unit twice, next to itself or before another
        const std::vector<Span> units = format_.units(text);
        if (units.empty()) break;
        const Span unit = pick(units);
        const std::size_t at = uniform(0, 1) ? unit.first + unit.second : pick(units).first;
        text.insert(at, text.substr(unit.first, unit.second));
        break;
      }
      case 4: {  // a unit gone, or two units swapped when they do not overlap
        const std::vector<Span> units = format_.units(text);
        if (units.empty()) break;
        Span a = pick(units), b = pick(units);
        if (uniform(0, 1) || a.first + a.second > b.first) {
          text.erase(a.first, a.second);
        } else {
          const std::string first = text.substr(a.first, a.second);
          const std::string second = text.substr(b.first, b.second);
          text.replace(b.first, b.second, first);
          text.replace(a.first, a.second, second);
        }
        break;
      }
      case 5: {  // a unit of another seed spliced in
        const std::string& other = pick(seeds_);
        const std::vector<Span> theirs = format_.units(other);
        const std::vector<Span> ours = format_.units(text);
        if (theirs.empty()) break;
        const Span unit = pick(theirs);
        text.insert(ours.empty() ? position(text) : pick(ours).first,
                    other.substr(unit.first, unit.second));
        break;
      }
      case 6: {  // a number replaced by an extreme value
        const auto found = numbers(text);
        if (found.empty()) break;
        const auto [at, length] = pick(found);
        text.replace(at, length, pick(format_.extremes));
        break;
      }
      case 7: {  // one word replaced by another of the text (names: loops, two parents, ...)
        const auto found = words(text);
        if (found.size() < 2) break;
        const auto [at, length] = pick(found);
        const auto [other, other_length] = pick(found);
        text.replace(at, length, text.substr(other, other_length));
        break;
      }
      case 8: {  // deep nesting, around the loaders' limits and far beyond
        static const std::vector<std::size_t> kDepths{2, 5, 50, 98, 99, 100, 101, 1000, 100000};
        text.insert(position(text), format_.nest(pick(kDepths), random_));
        break;
      }
      case 9:  // truncated
        text.resize(position(text));
        break;
      default:  // a piece of syntax anywhere
        text.insert(position(text), pick(format_.tokens));
        break;
    }
    return text;
  }

  std::vector<std::string> seeds_;
  Format format_;
  std::mt19937 random_;
};

/// Counts of a fuzz run and the first failures, with the inputs that caused them.
class Run {
 public:
  explicit Run(const char* name) : name_(name), start_(std::chrono::steady_clock::now()) {}

  void accepted() { ++accepted_; }
  void rejected() { ++rejected_; }
  /// Records a failure for `input` (shown escaped, cut at 2000 bytes); only the first few fail
  /// the test with their input, so that one bug does not bury the log.
  void failed(const std::string& what, const std::string& input) {
    if (++failures_ > 5) return;
    ADD_FAILURE() << name_ << ": " << what << "\ninput (" << input.size() << " bytes, escaped):\n"
                  << escaped(input.substr(0, 2000));
  }

  /// Prints and records the counts; both outcomes must have happened.
  void finish() const {
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const int inputs = accepted_ + rejected_ + failures_;
    std::printf("[ fuzz     ] %s: %d inputs, %d accepted, %d rejected, %d failed, %.2f s\n", name_,
                inputs, accepted_, rejected_, failures_, seconds);
    ::testing::Test::RecordProperty("inputs", inputs);
    ::testing::Test::RecordProperty("accepted", accepted_);
    ::testing::Test::RecordProperty("rejected", rejected_);
    // A fuzzer that rejects everything tests only the first check; one that accepts everything
    // is not mutating.
    EXPECT_GT(accepted_, 0) << name_;
    EXPECT_GT(rejected_, 0) << name_;
    EXPECT_EQ(failures_, 0) << name_;
  }

 private:
  static std::string escaped(const std::string& text) {
    std::string out;
    for (const char c : text) {
      const auto byte = static_cast<unsigned char>(c);
      if (byte == '\n' || (byte >= 0x20 && byte < 0x7F)) {
        out += c;
      } else {
        char hex[8];
        std::snprintf(hex, sizeof(hex), "\\x%02X", byte);
        out += hex;
      }
    }
    return out;
  }

  const char* name_;
  std::chrono::steady_clock::time_point start_;
  int accepted_ = 0;
  int rejected_ = 0;
  int failures_ = 0;
};

}  // namespace fuzz
