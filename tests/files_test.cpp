// Files given by name to the library's loaders: only regular files of at most kMaxFileBytes are
// read (core/files.hpp); a FIFO, /dev/zero, a directory or a file beyond the cap is refused before
// anything is read, with a LoadError naming the file, what it is and the cap. Here the shared
// function and the parameter file loader; the URDF loader in model_load_errors_test.cpp, Python's
// in python/tests/test_files.py, the ROS 2 node's in ros2/test/shell_test.cpp.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/files.hpp"
#include "support/fifo.hpp"

namespace ci = cartesian_impedance;
namespace fs = std::filesystem;

namespace {

// The LoadError's message of `load`, or a description of what happened instead.
std::string load_error(const std::function<void()>& load) {
  try {
    load();
  } catch (const ci::LoadError& error) {
    return error.what();
  } catch (const std::exception& error) {
    return std::string("not a LoadError: ") + error.what();
  }
  return "no error";
}

void expect_contains(const std::string& text, const std::vector<std::string>& parts) {
  for (const std::string& part : parts) {
    EXPECT_NE(text.find(part), std::string::npos) << "'" << part << "' not in: " << text;
  }
}

std::string scratch_file(const std::string& name, const std::string& content) {
  const std::string path = (fs::path(::testing::TempDir()) / name).string();
  std::ofstream(path, std::ios::binary) << content;
  return path;
}

}  // namespace

TEST(Files, RegularFileIsReadWhole) {
  const std::string content("a\0b\nc", 5);
  const std::string path = scratch_file("files_test_regular.txt", content);
  EXPECT_EQ(ci::read_regular_file(path, "test file"), content);
  EXPECT_EQ(ci::check_regular_file(path, "test file"), 5u);
  // A cap equal to the size reads the file; one below refuses it, naming both numbers.
  EXPECT_EQ(ci::read_regular_file(path, "test file", 5), content);
  expect_contains(load_error([&] { ci::read_regular_file(path, "test file", 4); }),
                  {"test file '" + path + "' has 5 bytes", "at most 4 bytes"});
}

TEST(Files, MissingFileAndDirectoryAreNamed) {
  expect_contains(load_error([] { ci::read_regular_file("/no/such/file.yaml", "parameter file"); }),
                  {"parameter file '/no/such/file.yaml' does not exist"});
  const std::string directory = ::testing::TempDir();
  expect_contains(load_error([&] { ci::read_regular_file(directory, "URDF file"); }),
                  {"URDF file '" + directory + "' is a directory, not a regular file"});
}

TEST(Files, FifoIsRefusedWithoutWaitingForAWriter) {
  const ci::test::Fifo fifo("files_test");
  expect_contains(load_error([&] { ci::read_regular_file(fifo.path(), "URDF file"); }),
                  {"URDF file '" + fifo.path() + "' is a FIFO (named pipe), not a regular file"});
}

TEST(Files, CharacterDeviceIsRefusedWithoutReading) {
  // /dev/zero never ends: read, it would fill memory up to the cap and beyond.
  expect_contains(load_error([] { ci::read_regular_file("/dev/zero", "parameter file"); }),
                  {"parameter file '/dev/zero' is a character device", "not a regular file"});
}

TEST(Files, FileBeyondTheCapIsRefusedBeforeReading) {
  // Sparse: the size is there without the bytes.
  const std::string path = (fs::path(::testing::TempDir()) / "files_test_large.yaml").string();
  std::ofstream(path).close();
  fs::resize_file(path, ci::kMaxFileBytes + 1);
  expect_contains(load_error([&] { ci::read_regular_file(path, "parameter file"); }),
                  {"parameter file '" + path + "' has 16777217 bytes",
                   "files of at most 16777216 bytes (16 MiB) are read"});
  fs::resize_file(path, ci::kMaxFileBytes);
  EXPECT_EQ(ci::read_regular_file(path, "parameter file").size(), ci::kMaxFileBytes);
  fs::remove(path);
}

// ---- the parameter file loader -------------------------------------------------------------

TEST(Files, ParameterLoaderRefusesFifoAndDevZero) {
  const ci::test::Fifo fifo("files_test_parameters");
  expect_contains(load_error([&] { ci::load_parameters(fifo.path()); }),
                  {"parameter file '" + fifo.path() + "' is a FIFO (named pipe)"});
  expect_contains(load_error([] { ci::load_parameters("/dev/zero"); }),
                  {"parameter file '/dev/zero' is a character device"});
}

TEST(Files, ParameterLoaderRefusesAFiftyMegabyteFileByItsSize) {
  // A list of 25 million numbers: read and parsed, it took about a minute and 8 GB or more.
  std::string text = "stiffness:\n  translation: [0";
  text.reserve(50u << 20);
  while (text.size() < (50u << 20)) text += ",0";
  text += "]\n";
  const std::string path = scratch_file("files_test_50mb.yaml", text);
  expect_contains(load_error([&] { ci::load_parameters(path); }),
                  {"parameter file '" + path + "' has " + std::to_string(text.size()) + " bytes",
                   "at most 16777216 bytes (16 MiB)"});
  fs::remove(path);
}
