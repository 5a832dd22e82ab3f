#include "cartesian_impedance/node/temporary_file.hpp"

#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::node {

TemporaryFile::TemporaryFile(const std::string& text, const std::string& suffix) {
  std::error_code ignored;
  std::string name =
      (std::filesystem::temp_directory_path(ignored) / ("cartesian_impedance_XXXXXX" + suffix))
          .string();
  const int fd = ::mkstemps(name.data(), static_cast<int>(suffix.size()));
  if (fd < 0) {
    throw Error("cannot create a temporary file '" + name + "': " + std::strerror(errno));
  }
  path_ = name;
  std::size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string reason = std::strerror(errno);
      ::close(fd);
      std::filesystem::remove(path_, ignored);
      throw Error("cannot write the temporary file '" + path_ + "': " + reason);
    }
    written += static_cast<std::size_t>(n);
  }
  ::close(fd);
}

TemporaryFile::~TemporaryFile() {
  std::error_code ignored;
  std::filesystem::remove(path_, ignored);
}

}  // namespace cartesian_impedance::node
