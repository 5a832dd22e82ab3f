#pragma once
/// @file
/// A file holding a text for as long as the object lives: the simulation's URDF loaders read
/// files, while a ROS shell may have only the text of robot_description.

#include <string>

namespace cartesian_impedance::node {

/// A new file in the temporary directory holding `text`, removed again with this object. The
/// simulation's URDF loaders (MuJoCo's, DART's) read files, while a shell may have only the text
/// of robot_description. The name is unique (mkstemps), so several nodes in one process or on
/// one machine do not overwrite each other's.
class TemporaryFile {
 public:
  /// `suffix` ends the name (".urdf": the loaders tell the format by it).
  /// @throws Error naming the path and the system's reason if it cannot be written.
  TemporaryFile(const std::string& text, const std::string& suffix);
  ~TemporaryFile();
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  const std::string& path() const noexcept { return path_; }

 private:
  std::string path_;
};

}  // namespace cartesian_impedance::node
