// A mesh MuJoCo 2.2 cannot read (COLLADA above all: ROS description packages ship their
// visual and often their collision meshes as .dae) turned into a binary STL with assimp, the
// library rviz and Gazebo read them with. The copy lives in a cache folder named by the source's
// path, size and time, so that a simulation reloaded (reset, a vector environment's workers) does
// not convert again, and a changed source is converted afresh.

#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <stdlib.h>
#include <unistd.h>
#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <functional>
#include <sstream>
#include <string>

#include "simulation_impl.hpp"

namespace cartesian_impedance::sim::detail {

std::string converted_mesh(const std::string& source, const std::string& what) {
  namespace fs = std::filesystem;
  std::error_code error_code;
  const auto size = fs::file_size(source, error_code);
  const auto time = fs::last_write_time(source, error_code);
  std::ostringstream key;
  key << source << '|' << size << '|' << time.time_since_epoch().count();
  std::ostringstream name;
  name << fs::path(source).stem().string() << '_' << std::hex << std::hash<std::string>{}(key.str())
       << ".stl";
  const fs::path folder = fs::temp_directory_path(error_code) / "cartesian_impedance_meshes";
  const fs::path target = folder / name.str();
  if (fs::is_regular_file(target, error_code)) return target.string();

  Assimp::Importer importer;
  // Keep the file's own axes (a URDF mesh is in its link's frame, whatever the exporter called
  // "up"); COLLADA's <unit meter=...> is applied, as rviz and Gazebo apply it.
  importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, true);
  const aiScene* scene = importer.ReadFile(
      source, aiProcess_Triangulate | aiProcess_PreTransformVertices |
                  aiProcess_JoinIdenticalVertices | aiProcess_RemoveRedundantMaterials);
  if (scene == nullptr || scene->mNumMeshes == 0) {
    throw Error(what + " found at '" + source + "' cannot be read by assimp" +
                (scene == nullptr ? ": " + std::string(importer.GetErrorString())
                                  : ": it has no triangles"));
  }
  fs::create_directories(folder, error_code);
  // Written under a unique name and renamed into place: processes converting the same file at
  // once (forked workers) each rename a complete file.
  std::string temporary = (folder / (name.str() + ".XXXXXX")).string();
  const int fd = ::mkstemp(temporary.data());
  if (fd < 0) {
    throw Error(what + ": cannot write its STL copy in '" + folder.string() +
                "': " + std::strerror(errno));
  }
  ::close(fd);
  Assimp::Exporter exporter;
  if (exporter.Export(scene, "stlb", temporary) != aiReturn_SUCCESS) {
    fs::remove(temporary, error_code);
    throw Error(what + " found at '" + source +
                "': assimp cannot write it as STL: " + exporter.GetErrorString());
  }
  fs::rename(temporary, target, error_code);
  if (error_code) {
    fs::remove(temporary, error_code);
    throw Error(what + ": cannot move its STL copy to '" + target.string() + "'");
  }
  return target.string();
}

}  // namespace cartesian_impedance::sim::detail
