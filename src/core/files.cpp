#include "cartesian_impedance/core/files.hpp"

#include <filesystem>
#include <fstream>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance {
namespace {

namespace fs = std::filesystem;

std::string named(std::string_view what, const std::string& path) {
  return std::string(what) + " '" + path + "'";
}

// What a file of type `type` is, for "... is <this>, not a regular file".
const char* kind_of(fs::file_type type) {
  switch (type) {
    case fs::file_type::directory:
      return "a directory";
    case fs::file_type::fifo:
      return "a FIFO (named pipe)";
    case fs::file_type::character:
      return "a character device (such as /dev/zero or a terminal)";
    case fs::file_type::block:
      return "a block device";
    case fs::file_type::socket:
      return "a socket";
    default:
      return "of a kind that is not a regular file";
  }
}

std::string bytes_text(std::uintmax_t bytes) {
  std::string text = std::to_string(bytes) + " bytes";
  if (bytes >= 1024 * 1024 && bytes % (1024 * 1024) == 0) {
    text += " (" + std::to_string(bytes / (1024 * 1024)) + " MiB)";
  }
  return text;
}

[[noreturn]] void too_large(std::string_view what, const std::string& path, std::string size,
                            std::uintmax_t max_bytes) {
  throw LoadError(named(what, path) + " has " + size + "; files of at most " +
                  bytes_text(max_bytes) + " are read");
}

}  // namespace

std::uintmax_t check_regular_file(const std::string& path, std::string_view what,
                                  std::uintmax_t max_bytes) {
  std::error_code error;
  // status() follows symbolic links: /dev/stdin is judged by what it points to (a pipe, a tty).
  const fs::file_status status = fs::status(path, error);
  if (status.type() == fs::file_type::not_found) {
    throw LoadError(named(what, path) + " does not exist");
  }
  if (error) throw LoadError(named(what, path) + " cannot be examined: " + error.message());
  if (status.type() != fs::file_type::regular) {
    // Checked before anything opens it: opening a FIFO waits for a writer, reading /dev/zero
    // never ends.
    throw LoadError(named(what, path) + " is " + kind_of(status.type()) + ", not a regular file");
  }
  const std::uintmax_t size = fs::file_size(path, error);
  if (error) throw LoadError(named(what, path) + " cannot be examined: " + error.message());
  if (size > max_bytes) too_large(what, path, bytes_text(size), max_bytes);
  return size;
}

std::string read_regular_file(const std::string& path, std::string_view what,
                              std::uintmax_t max_bytes) {
  check_regular_file(path, what, max_bytes);
  std::ifstream file(path, std::ios::binary);
  if (!file.is_open()) throw LoadError(named(what, path) + " cannot be opened for reading");
  std::string text;
  char buffer[65536];
  // Bounded by the cap, not by the size seen above: the file may have grown since.
  while (file && text.size() <= max_bytes) {
    file.read(buffer, sizeof(buffer));
    text.append(buffer, static_cast<std::size_t>(file.gcount()));
  }
  if (file.bad()) throw LoadError(named(what, path) + " cannot be read");
  if (text.size() > max_bytes)
    too_large(what, path, "more than " + bytes_text(max_bytes), max_bytes);
  return text;
}

}  // namespace cartesian_impedance
