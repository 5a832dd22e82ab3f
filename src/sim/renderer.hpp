#pragma once
// Internal to the sim target: offscreen rendering through EGL (loaded at run time, so the library
// works on machines without libEGL and only render_png() fails) and PNG output through libpng.

#include <mujoco/mujoco.h>

#include <memory>
#include <string>

#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::sim::detail {

/// Why offscreen rendering cannot work in this process, or "" if it can. Tries once per process.
const std::string& offscreen_rendering_failure();

/// One OpenGL context (EGL, surfaceless) with MuJoCo's rendering context and a scene. Made current
/// on the calling thread for each render.
class Renderer {
 public:
  /// @throw Error if EGL or OpenGL is unavailable.
  Renderer();
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Renders `data` of `model` with camera `camera_id` (-1: a free camera fitted to the scene)
  /// and the overlay's caption, arrows and frames, plus the geoms of `ghost` (same model, its
  /// own kinematics; nullptr: none) drawn translucent, and writes an RGB PNG. May enlarge
  /// model->vis.global.offwidth/offheight to fit the image. Arguments are checked by the caller.
  /// @throw Error if OpenGL fails or the file cannot be written.
  void render_png(mjModel* model, mjData* data, const std::string& path, int width, int height,
                  int camera_id, const RenderOverlay& overlay, mjData* ghost);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace cartesian_impedance::sim::detail
