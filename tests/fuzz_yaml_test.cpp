// Mutation fuzzing of the YAML parameter loader, from the project's own parameter files. Every
// input must either load into parameters that validate and survive a round trip through
// parameters_to_yaml, or be rejected with cartesian_impedance::Error; anything else (another
// exception, a crash, a sanitizer report) fails. Deterministic: fixed seeds.

#include <gtest/gtest.h>

#include <exception>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <typeinfo>
#include <vector>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "support/mutator.hpp"

namespace ci = cartesian_impedance;

namespace {

std::string read_source_file(const std::string& relative) {
  std::ifstream file(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/" + relative);
  return std::string(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
}

fuzz::Format yaml_format() {
  fuzz::Format format;
  format.extremes = {".nan",
                     ".NaN",
                     ".inf",
                     "-.inf",
                     "+.inf",
                     "nan",
                     "inf",
                     "1e308",
                     "-1e308",
                     "1.7976931348623157e308",
                     "1e309",
                     "1e400",
                     "-1e400",
                     "-0",
                     "-0.0",
                     "5e-324",
                     "1e-400",
                     "99999999999999999999999",
                     "-99999999999999999999999",
                     "0x10",
                     "0o17",
                     "0b1",
                     "1_000",
                     "'5'",
                     "\"5\"",
                     "' 5'",
                     "~",
                     "null",
                     "",
                     "[]",
                     "{}",
                     "[1, 2]",
                     "{a: 1}",
                     "true",
                     "yes",
                     "&a 5",
                     "*a",
                     "!!str 5",
                     "!!float 5",
                     "|\n  5",
                     "5 # comment",
                     "1e3",
                     "0",
                     "1",
                     "-1"};
  format.tokens = {"---\n",
                   "...\n",
                   "? ",
                   ": ",
                   "- ",
                   "&a ",
                   "*a",
                   "!!str ",
                   "!foo ",
                   "'",
                   "\"",
                   "#",
                   "\t",
                   "\n",
                   "\n  ",
                   "  ",
                   "{",
                   "}",
                   "[",
                   "]",
                   ",",
                   "|\n",
                   ">\n",
                   "<<: ",
                   "%YAML 1.2\n---\n",
                   "? [a, b]\n: 1\n",
                   "stiffness:\n  translation: 1\n",
                   "\xEF\xBB\xBF",
                   std::string(1, '\0'),
                   "\xFF"};
  format.nest = [](std::size_t count, std::mt19937& random) {
    static const std::vector<std::pair<std::string, std::string>> kPairs{
        {"[", "]"}, {"{", "}"}, {"{a: ", "}"}, {"[{a: ", "}]"}};
    const auto& [open, close] =
        kPairs[std::uniform_int_distribution<std::size_t>(0, kPairs.size() - 1)(random)];
    std::string text;
    text.reserve(count * (open.size() + close.size()));
    for (std::size_t i = 0; i < count; ++i) text += open;
    if (std::uniform_int_distribution<int>(0, 1)(random)) {
      for (std::size_t i = 0; i < count; ++i) text += close;
    }
    return text;
  };
  format.units = fuzz::line_blocks;
  return format;
}

// One input through the property; counts the outcome in `run`.
void check_input(const std::string& input, fuzz::Run& run) {
  ci::Parameters parameters;
  try {
    parameters = ci::parameters_from_yaml(input, "fuzz.yaml");
  } catch (const ci::Error&) {
    run.rejected();
    return;
  } catch (const std::exception& other) {
    run.failed(std::string("threw ") + typeid(other).name() + ": " + other.what(), input);
    return;
  } catch (...) {
    run.failed("threw something that is not a std::exception", input);
    return;
  }
  // Accepted: the parameters must be valid and must come back unchanged from their YAML.
  try {
    ci::validate(parameters);
    const std::string yaml = ci::parameters_to_yaml(parameters);
    const ci::Parameters back = ci::parameters_from_yaml(yaml, "round trip");
    if (ci::parameters_to_yaml(back) != yaml) {
      run.failed("the round trip changed the parameters:\n" + yaml, input);
      return;
    }
  } catch (const std::exception& error) {
    run.failed(std::string("accepted, but then: ") + error.what(), input);
    return;
  }
  run.accepted();
}

void fuzz_yaml(const char* name, std::uint32_t seed, int inputs) {
  fuzz::Mutator mutator(
      {read_source_file("config/panda.yaml"), read_source_file("config/iiwa14.yaml"),
       ci::parameters_to_yaml(ci::Parameters())},
      yaml_format(), seed);
  for (const std::string& file : mutator.seeds()) ASSERT_GT(file.size(), 100u);
  fuzz::Run run(name);
  for (int i = 0; i < inputs; ++i) {
    check_input(mutator.next(static_cast<std::size_t>(i) % mutator.seeds().size()), run);
  }
  run.finish();
}

}  // namespace

TEST(FuzzYaml, MutatedParameterFilesLoadOrAreRejectedWithError) {
  fuzz_yaml("yaml", 20240601u, 3000);
}
