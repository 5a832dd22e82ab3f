// The bounds every converter of a source into the decoder's value tree keeps (ParameterTreeGuard
// in parameter_tree.hpp): depth, cycles and the number of values, each refused with a
// ParameterError naming the path; and the YAML adapter keeping them while it reads. Python's
// converter is fuzzed in python/tests/test_parameter_fuzz.py, the ROS 1 converter in
// ros/test/unit_test.cpp.

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameter_tree.hpp"

namespace ci = cartesian_impedance;
using Guard = ci::ParameterTreeGuard;
using Reason = ci::ParameterError::Reason;

namespace {

// The message of the ParameterError `action` throws for an oversized tree, or what it did instead.
std::string oversized(const std::function<void()>& action) {
  try {
    action();
  } catch (const ci::ParameterError& error) {
    if (error.reason() != Reason::oversized) return std::string("another reason: ") + error.what();
    return error.what();
  } catch (const std::exception& error) {
    return std::string("not a ParameterError: ") + error.what();
  }
  return "no error";
}

// Enters `levels` nested lists, the k-th at path "a" + "[0]" * k.
void nest(Guard& guard, std::size_t levels, const std::string& path = "a") {
  if (levels == 0) return;
  const Guard::Level level = guard.enter(nullptr, path, "here");
  nest(guard, levels - 1, path + "[0]");
}

}  // namespace

TEST(ParameterTreeGuard, DepthIsBoundedAndNamedByPath) {
  Guard guard;
  nest(guard, Guard::kMaxDepth);  // as deep as allowed
  EXPECT_EQ(guard.depth(), 0u);   // every level left again
  std::string path = "a";
  for (std::size_t i = 0; i < Guard::kMaxDepth; ++i) path += "[0]";
  EXPECT_EQ(oversized([&] { nest(guard, Guard::kMaxDepth + 1); }),
            "here: '" + path +
                "' is nested too deeply: more than 32 levels of lists and maps; parameters are "
                "nested at most 4 levels deep, with a list of numbers below");
  EXPECT_EQ(guard.depth(), 0u);  // the levels entered before the error are left too
}

TEST(ParameterTreeGuard, ACycleNamesBothPathsAndASharedValueIsNoCycle) {
  Guard guard;
  const int list = 0, other = 0;
  {
    const Guard::Level outer = guard.enter(&list, "stiffness.translation");
    // The same object beside itself (a YAML alias used twice, a Python list in two places).
    { const Guard::Level first = guard.enter(&other, "stiffness.translation[0]"); }
    { const Guard::Level second = guard.enter(&other, "stiffness.translation[1]"); }
    EXPECT_EQ(oversized([&] {
                const Guard::Level inner =
                    guard.enter(&list, "stiffness.translation[2]", "f.yaml:3");
              }),
              "f.yaml:3: 'stiffness.translation[2]' is 'stiffness.translation' again: a list or "
              "map that contains itself has no end; a parameter value is a tree");
  }
  const int top = 0;
  const Guard::Level root = guard.enter(&top, "");
  EXPECT_EQ(oversized([&] { const Guard::Level inner = guard.enter(&top, "stiffness"); }),
            "'stiffness' is the top level again: a list or map that contains itself has no end; "
            "a parameter value is a tree");
}

TEST(ParameterTreeGuard, ValuesAreCountedUpToTheCap) {
  Guard guard;
  for (std::size_t i = 0; i < Guard::kMaxValues; ++i) guard.count("a");
  EXPECT_EQ(oversized([&] { guard.count("b.c", "f.yaml:9"); }),
            "f.yaml:9: more than 100000 values (the next at 'b.c'); a parameter set holds a few "
            "hundred");
}

// ---- the YAML adapter ----------------------------------------------------------------------

TEST(ParameterTreeGuard, YamlNestedBeyondTheBoundIsRefusedByPath) {
  // Deep enough for the guard, not for yaml-cpp's own bound on its parser's recursion.
  std::string yaml = "stiffness:\n  translation: ";
  for (int i = 0; i < 40; ++i) yaml += "[";
  for (int i = 0; i < 40; ++i) yaml += "]";
  const std::string message = oversized([&] { ci::parameters_from_yaml(yaml, "deep.yaml"); });
  EXPECT_EQ(message.rfind("deep.yaml:2: 'stiffness.translation[0][0]", 0), 0u) << message;
  EXPECT_NE(message.find("is nested too deeply: more than 32 levels"), std::string::npos)
      << message;
}

TEST(ParameterTreeGuard, YamlTextIsCountedWhileItIsParsed) {
  // 25 million numbers in 50 MB of text (what no file loader reads: they stop at 16 MiB, but the
  // text may come from elsewhere, as Parameters.from_yaml in Python): yaml-cpp's own tree of it
  // took about a minute and 8 to 12 GB (or std::bad_alloc); it is refused at the value after the
  // cap.
  std::string yaml = "stiffness:\n  translation: [0";
  yaml.reserve(50u << 20);
  while (yaml.size() < (50u << 20)) yaml += ",0";
  yaml += "]\n";
  EXPECT_EQ(oversized([&] { ci::parameters_from_yaml(yaml, "big.yaml"); }),
            "big.yaml:2: more than 100000 values; a parameter set holds a few hundred");
  // Refused before yaml-cpp builds its tree, at hundreds of bytes per node: in a child process,
  // whose peak resident memory then holds the text and its parser's copy (about 100 MB), far
  // below the 8 GB and more that tree took (and what sanitizers add).
  EXPECT_EXIT(
      {
        try {
          ci::parameters_from_yaml(yaml, "big.yaml");
        } catch (const ci::Error&) {
        }
        rusage usage{};
        getrusage(RUSAGE_SELF, &usage);
        std::exit(usage.ru_maxrss < 2 * 1024 * 1024 ? 0 : 1);  // [kB]
      },
      ::testing::ExitedWithCode(0), "");
}

TEST(ParameterTreeGuard, YamlKeysCountAsValuesUpToTheCapExactly) {
  // A map of n keys with a number each is 1 + 2 n values: 49999 keys fit, 50000 do not.
  const auto map_of = [](int keys) {
    std::string yaml;
    for (int i = 0; i < keys; ++i) yaml += "k" + std::to_string(i) + ": 1\n";
    return yaml;
  };
  const ci::ParameterValue tree = ci::parameter_tree_from_yaml(map_of(49999), "keys.yaml");
  EXPECT_EQ(tree.as_map().size(), 49999u);
  EXPECT_EQ(oversized([&] { ci::parameter_tree_from_yaml(map_of(50000), "keys.yaml"); }),
            "keys.yaml:50000: more than 100000 values; a parameter set holds a few hundred");
}
