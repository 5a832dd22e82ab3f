#include "renderer.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <dlfcn.h>
#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "simulation_impl.hpp"

namespace cartesian_impedance::sim::detail {
namespace {

std::string hex(EGLint code) {
  char text[16];
  std::snprintf(text, sizeof(text), "0x%04X", static_cast<unsigned>(code));
  return text;
}

// libEGL is opened at run time rather than linked: a machine without it can still load the
// library and simulate; only rendering reports the problem. The types come from the EGL headers,
// the functions from dlsym.
struct Egl {
  void* library = nullptr;
  decltype(&::eglGetProcAddress) get_proc_address = nullptr;
  decltype(&::eglGetError) get_error = nullptr;
  decltype(&::eglGetDisplay) get_display = nullptr;
  decltype(&::eglInitialize) initialize = nullptr;
  decltype(&::eglChooseConfig) choose_config = nullptr;
  decltype(&::eglBindAPI) bind_api = nullptr;
  decltype(&::eglCreateContext) create_context = nullptr;
  decltype(&::eglDestroyContext) destroy_context = nullptr;
  decltype(&::eglMakeCurrent) make_current = nullptr;
  decltype(&::eglGetCurrentContext) get_current_context = nullptr;
  decltype(&::eglGetCurrentDisplay) get_current_display = nullptr;
  decltype(&::eglGetCurrentSurface) get_current_surface = nullptr;
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLConfig config = nullptr;
  std::string failure;  // "" when display and config are usable
};

template <typename Function>
bool load_symbol(void* library, const char* name, Function& function) {
  function = reinterpret_cast<Function>(dlsym(library, name));
  return function != nullptr;
}

Egl open_egl() {
  Egl egl;
  // RTLD_GLOBAL: MuJoCo's OpenGL loader looks the EGL entry points up in the global namespace.
  egl.library = dlopen("libEGL.so.1", RTLD_NOW | RTLD_GLOBAL);
  if (egl.library == nullptr) {
    const char* why = dlerror();
    egl.failure = std::string("cannot load libEGL.so.1 (") + (why != nullptr ? why : "?") +
                  "); install libegl1 and an EGL driver such as libegl-mesa0";
    return egl;
  }
  const bool complete = load_symbol(egl.library, "eglGetProcAddress", egl.get_proc_address) &&
                        load_symbol(egl.library, "eglGetError", egl.get_error) &&
                        load_symbol(egl.library, "eglGetDisplay", egl.get_display) &&
                        load_symbol(egl.library, "eglInitialize", egl.initialize) &&
                        load_symbol(egl.library, "eglChooseConfig", egl.choose_config) &&
                        load_symbol(egl.library, "eglBindAPI", egl.bind_api) &&
                        load_symbol(egl.library, "eglCreateContext", egl.create_context) &&
                        load_symbol(egl.library, "eglDestroyContext", egl.destroy_context) &&
                        load_symbol(egl.library, "eglMakeCurrent", egl.make_current) &&
                        load_symbol(egl.library, "eglGetCurrentContext", egl.get_current_context) &&
                        load_symbol(egl.library, "eglGetCurrentDisplay", egl.get_current_display) &&
                        load_symbol(egl.library, "eglGetCurrentSurface", egl.get_current_surface);
  if (!complete) {
    egl.failure = "libEGL.so.1 lacks an EGL 1.4 entry point";
    return egl;
  }

  // Prefer Mesa's surfaceless platform (no display server, no GPU needed); fall back to the
  // default display (e.g. a vendor driver with its own headless support).
  std::string attempts;
  const auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      egl.get_proc_address("eglGetPlatformDisplayEXT"));
  if (get_platform_display != nullptr) {
    EGLDisplay display =
        get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    EGLint major = 0;
    EGLint minor = 0;
    if (display != EGL_NO_DISPLAY && egl.initialize(display, &major, &minor) == EGL_TRUE) {
      egl.display = display;
    } else {
      attempts += "surfaceless platform: EGL error " + hex(egl.get_error()) + "; ";
    }
  } else {
    attempts += "no eglGetPlatformDisplayEXT; ";
  }
  if (egl.display == EGL_NO_DISPLAY) {
    EGLDisplay display = egl.get_display(EGL_DEFAULT_DISPLAY);
    EGLint major = 0;
    EGLint minor = 0;
    if (display != EGL_NO_DISPLAY && egl.initialize(display, &major, &minor) == EGL_TRUE) {
      egl.display = display;
    } else {
      attempts += "default display: EGL error " + hex(egl.get_error());
      egl.failure = "no EGL display could be initialised (" + attempts +
                    "); install an EGL driver such as libegl-mesa0 with libgl1-mesa-dri";
      return egl;
    }
  }

  // clang-format off
  const EGLint attributes[] = {EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8,
                               EGL_ALPHA_SIZE, 8, EGL_DEPTH_SIZE, 24, EGL_STENCIL_SIZE, 8,
                               EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                               EGL_SURFACE_TYPE, EGL_PBUFFER_BIT,  // no window, no display
                               EGL_NONE};
  // clang-format on
  EGLint count = 0;
  if (egl.choose_config(egl.display, attributes, &egl.config, 1, &count) != EGL_TRUE || count < 1) {
    egl.failure = "no EGL configuration with 8-bit RGBA, 24-bit depth and desktop OpenGL";
    return egl;
  }
  if (egl.bind_api(EGL_OPENGL_API) != EGL_TRUE) {
    egl.failure = "EGL cannot bind the desktop OpenGL API (EGL error " + hex(egl.get_error()) + ")";
  }
  return egl;
}

Egl& egl() {
  static Egl instance = open_egl();  // thread-safe one-time initialisation
  return instance;
}

// Creates a context; "" on success, else why not.
std::string create_context(EGLContext& context) {
  Egl& api = egl();
  if (!api.failure.empty()) return api.failure;
  api.bind_api(EGL_OPENGL_API);  // the bound API is per thread
  context = api.create_context(api.display, api.config, EGL_NO_CONTEXT, nullptr);
  if (context == EGL_NO_CONTEXT) {
    return "eglCreateContext failed (EGL error " + hex(api.get_error()) + ")";
  }
  return "";
}

// Remembers the calling thread's current EGL context and restores it on destruction.
class CurrentContextGuard {
 public:
  CurrentContextGuard()
      : display_(egl().get_current_display()),
        draw_(egl().get_current_surface(EGL_DRAW)),
        read_(egl().get_current_surface(EGL_READ)),
        context_(egl().get_current_context()) {}
  ~CurrentContextGuard() {
    if (display_ != EGL_NO_DISPLAY) {
      egl().make_current(display_, draw_, read_, context_);
    } else {
      egl().make_current(egl().display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    }
  }
  CurrentContextGuard(const CurrentContextGuard&) = delete;
  CurrentContextGuard& operator=(const CurrentContextGuard&) = delete;

 private:
  EGLDisplay display_;
  EGLSurface draw_;
  EGLSurface read_;
  EGLContext context_;
};

std::string check_offscreen_rendering() {
  EGLContext context = EGL_NO_CONTEXT;
  std::string failure = create_context(context);
  if (!failure.empty()) return failure;
  Egl& api = egl();
  {
    CurrentContextGuard guard;
    if (api.make_current(api.display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE) {
      failure = "eglMakeCurrent without a surface failed (EGL error " + hex(api.get_error()) +
                "; EGL_KHR_surfaceless_context is needed)";
    } else {
      using GetString = const unsigned char* (*)(unsigned int);
      const auto get_string = reinterpret_cast<GetString>(api.get_proc_address("glGetString"));
      constexpr unsigned int kGlVersion = 0x1F02;  // GL_VERSION
      if (get_string == nullptr || get_string(kGlVersion) == nullptr) {
        failure = "an OpenGL context was created but glGetString(GL_VERSION) failed";
      }
    }
  }
  api.destroy_context(api.display, context);
  return failure;
}

}  // namespace

const std::string& offscreen_rendering_failure() {
  static const std::string failure = check_offscreen_rendering();
  return failure;
}

struct Renderer::State {
  EGLContext context = EGL_NO_CONTEXT;
  bool made = false;  // mjr context and scene exist
  mjrContext mjr{};
  mjvScene scene{};
  mjvOption option{};
};

Renderer::Renderer() : state_(std::make_unique<State>()) {
  const std::string& failure = offscreen_rendering_failure();
  if (!failure.empty()) throw Error("offscreen rendering is unavailable: " + failure);
  const std::string why = create_context(state_->context);
  if (!why.empty()) throw Error("offscreen rendering is unavailable: " + why);
  mjr_defaultContext(&state_->mjr);
  mjv_defaultScene(&state_->scene);
  mjv_defaultOption(&state_->option);
}

Renderer::~Renderer() {
  Egl& api = egl();
  if (state_->made) {
    CurrentContextGuard guard;
    if (api.make_current(api.display, EGL_NO_SURFACE, EGL_NO_SURFACE, state_->context) ==
        EGL_TRUE) {
      mjr_freeContext(&state_->mjr);
    }
    mjv_freeScene(&state_->scene);
  }
  api.destroy_context(api.display, state_->context);
}

namespace {

// Room for what the overlay adds to the model's own geoms.
constexpr int kMaxSceneGeoms = 4000;

mjvGeom* add_geom(mjvScene& scene) {
  if (scene.ngeom >= scene.maxgeom) return nullptr;  // a full scene drops the rest, as MuJoCo does
  return &scene.geoms[scene.ngeom++];
}

void set_label(mjvGeom& geom, const std::string& label) {
  const std::size_t n = std::min(label.size(), sizeof(geom.label) - 1);
  std::copy(label.begin(), label.begin() + static_cast<std::ptrdiff_t>(n), geom.label);
  geom.label[n] = '\0';
}

void add_arrow(mjvScene& scene, const Eigen::Vector3d& from, const Eigen::Vector3d& to,
               double width, const float rgba[4], const std::string& label) {
  if ((to - from).norm() < 1e-6) return;
  if (mjvGeom* geom = add_geom(scene)) {
    mjv_initGeom(geom, mjGEOM_ARROW, nullptr, nullptr, nullptr, rgba);
    mjv_makeConnector(geom, mjGEOM_ARROW, width, from.x(), from.y(), from.z(), to.x(), to.y(),
                      to.z());
    // MuJoCo 2.2's renderer draws an arrow over half its size[2] (shaft to a third, head to a
    // half; measured against a cylinder connector of the same ends).
    geom->size[2] *= 2.0f;
    geom->category = mjCAT_DECOR;
    geom->transparent = rgba[3] < 1.0f;
  }
  // MuJoCo writes a geom's label at its origin, which for an arrow is the tail, inside the
  // robot: the text goes on an invisible geom at the head.
  if (label.empty()) return;
  if (mjvGeom* text = add_geom(scene)) {
    const mjtNum position[3] = {to.x(), to.y(), to.z()};
    mjv_initGeom(text, mjGEOM_LABEL, nullptr, position, nullptr, rgba);
    text->category = mjCAT_DECOR;
    set_label(*text, label);
  }
}

// The twelve edges of an axis-aligned box as thin cylinders.
void add_box_edges(mjvScene& scene, const RenderBox& box, double width) {
  const float rgba[4] = {box.rgba[0], box.rgba[1], box.rgba[2], box.rgba[3]};
  const auto corner = [&](int bits) {
    return Eigen::Vector3d((bits & 1) ? box.max.x() : box.min.x(),
                           (bits & 2) ? box.max.y() : box.min.y(),
                           (bits & 4) ? box.max.z() : box.min.z());
  };
  for (int from = 0; from < 8; ++from) {
    for (int axis = 0; axis < 3; ++axis) {
      if (from & (1 << axis)) continue;  // each edge once, from its lower end
      const Eigen::Vector3d a = corner(from), b = corner(from | (1 << axis));
      if ((b - a).norm() < 1e-9) continue;
      if (mjvGeom* geom = add_geom(scene)) {
        mjv_initGeom(geom, mjGEOM_CYLINDER, nullptr, nullptr, nullptr, rgba);
        mjv_makeConnector(geom, mjGEOM_CYLINDER, width, a.x(), a.y(), a.z(), b.x(), b.y(), b.z());
        geom->category = mjCAT_DECOR;
        geom->transparent = rgba[3] < 1.0f;
      }
    }
  }
  if (box.label.empty()) return;
  if (mjvGeom* text = add_geom(scene)) {
    const mjtNum position[3] = {box.max.x(), box.max.y(), box.max.z()};
    mjv_initGeom(text, mjGEOM_LABEL, nullptr, position, nullptr, rgba);
    text->category = mjCAT_DECOR;
    set_label(*text, box.label);
  }
}

// What the free camera must keep in view: a sphere.
struct Extent {
  Eigen::Vector3d center;
  double radius;
};

// Centres the free camera on everything in `extents` and backs it off until all of it is inside
// the field of view (with a margin, and room for the caption at the top).
void fit_camera(mjvCamera& view, const std::vector<Extent>& extents, double fovy_degrees,
                double aspect, double caption_fraction) {
  if (extents.empty()) return;
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d high = -low;
  for (const Extent& e : extents) {
    low = low.cwiseMin(e.center - Eigen::Vector3d::Constant(e.radius));
    high = high.cwiseMax(e.center + Eigen::Vector3d::Constant(e.radius));
  }
  const Eigen::Vector3d center = 0.5 * (low + high);
  const double azimuth = view.azimuth * M_PI / 180.0, elevation = view.elevation * M_PI / 180.0;
  // mjv_updateCamera's axes of a free camera.
  const Eigen::Vector3d forward(std::cos(elevation) * std::cos(azimuth),
                                std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
  const Eigen::Vector3d up(-std::sin(elevation) * std::cos(azimuth),
                           -std::sin(elevation) * std::sin(azimuth), std::cos(elevation));
  const Eigen::Vector3d right = forward.cross(up);
  const double margin = 1.06;
  const double tan_vertical =
      std::tan(0.5 * fovy_degrees * M_PI / 180.0) * (1.0 - caption_fraction);
  const double tan_horizontal = std::tan(0.5 * fovy_degrees * M_PI / 180.0) * aspect;
  double distance = 0.0;
  for (const Extent& e : extents) {
    const Eigen::Vector3d d = e.center - center;
    // A point at depth z (distance + d.forward) is in view if |x| <= z tan(half angle).
    const double r = margin * e.radius;
    distance =
        std::max({distance, margin * (std::abs(d.dot(right)) + r) / tan_horizontal - d.dot(forward),
                  margin * (std::abs(d.dot(up)) + r) / tan_vertical - d.dot(forward)});
  }
  // The caption covers the top: the scene moves down into the rest of the picture.
  const Eigen::Vector3d lookat = center + caption_fraction * tan_vertical * distance * up;
  for (int i = 0; i < 3; ++i) view.lookat[i] = lookat[i];
  view.distance = distance;
}

// Fills the background (depth at the far plane) with a vertical gradient, for a model without a
// skybox: MuJoCo clears it to black.
void paint_sky(std::vector<unsigned char>& rgb, const std::vector<float>& depth, int width,
               int height) {
  for (int row = 0; row < height; ++row) {
    // OpenGL rows start at the bottom.
    const double t = static_cast<double>(row) / std::max(1, height - 1);
    const unsigned char colour[3] = {static_cast<unsigned char>(240 - 100 * t),
                                     static_cast<unsigned char>(245 - 70 * t),
                                     static_cast<unsigned char>(250 - 35 * t)};
    for (int column = 0; column < width; ++column) {
      const std::size_t pixel = static_cast<std::size_t>(row) * width + column;
      if (depth[pixel] < 1.0f) continue;
      std::copy(colour, colour + 3, rgb.begin() + static_cast<std::ptrdiff_t>(3 * pixel));
    }
  }
}

// Breaks each line of `text` at spaces so that none is wider than `width` pixels in the font
// of `widths` (a word longer than that stays whole).
std::string wrap(const std::string& text, const int widths[127], int width) {
  const auto width_of = [&](const std::string& s) {
    int w = 0;
    for (const char c : s) w += (c > 0 && c < 127) ? widths[static_cast<int>(c)] : widths['?'];
    return w;
  };
  std::string wrapped, line;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    std::string rest = text.substr(start, end - start);
    while (width_of(rest) > width) {
      std::size_t cut = rest.size();
      while (cut > 0 && (rest[cut - 1] != ' ' || width_of(rest.substr(0, cut - 1)) > width)) --cut;
      if (cut == 0) break;  // no space to break at
      wrapped += rest.substr(0, cut - 1) + "\n  ";
      rest = rest.substr(cut);
    }
    wrapped += rest;
    if (end == text.size()) break;
    wrapped += '\n';
    start = end + 1;
  }
  return wrapped;
}

bool has_skybox(const mjModel* model) {
  for (int i = 0; i < model->ntex; ++i) {
    if (model->tex_type[i] == mjTEXTURE_SKYBOX) return true;
  }
  return false;
}

}  // namespace

void Renderer::render_png(mjModel* model, mjData* data, const std::string& path, int width,
                          int height, int camera_id, const RenderOverlay& overlay, mjData* ghost) {
  Egl& api = egl();
  CurrentContextGuard guard;
  if (api.make_current(api.display, EGL_NO_SURFACE, EGL_NO_SURFACE, state_->context) != EGL_TRUE) {
    throw Error("eglMakeCurrent failed (EGL error " + hex(api.get_error()) + ")");
  }
  State& s = *state_;
  if (!s.made || s.mjr.offWidth < width || s.mjr.offHeight < height) {
    // The offscreen framebuffer is sized from the model's visual options at context creation.
    MujocoErrorTrap trap;
    if (s.made) {
      mjr_freeContext(&s.mjr);
      mjv_freeScene(&s.scene);
      s.made = false;
    }
    model->vis.global.offwidth = std::max(model->vis.global.offwidth, width);
    model->vis.global.offheight = std::max(model->vis.global.offheight, height);
    mjr_defaultContext(&s.mjr);
    // Captions of an 800 x 600 picture are readable at 150 %.
    mjr_makeContext(model, &s.mjr, mjFONTSCALE_150);
    mjv_defaultScene(&s.scene);
    mjv_makeScene(model, &s.scene, kMaxSceneGeoms);
    s.made = true;
  }
  mjr_setBuffer(mjFB_OFFSCREEN, &s.mjr);
  if (s.mjr.currentBuffer != mjFB_OFFSCREEN) {
    throw Error("the OpenGL context has no offscreen framebuffer");
  }
  // A floor that mirrors the arm shows what looks like a second, upside-down arm.
  s.scene.flags[mjRND_REFLECTION] = 0;
  // MuJoCo 2.2 lets every geom cast a shadow, a ghost's too, which then reads as a second arm's
  // shadow: pictures with a ghost have none.
  s.scene.flags[mjRND_SHADOW] = ghost == nullptr ? 1 : 0;

  mjvCamera view;
  mjv_defaultFreeCamera(model, &view);
  if (camera_id >= 0) {
    view.type = mjCAMERA_FIXED;
    view.fixedcamid = camera_id;
  } else {
    // From the robot's right side, a little to the front (it faces +x, so tables in front of it
    // do not hide it), slightly above.
    view.azimuth = std::isnan(overlay.azimuth) ? 105.0 : overlay.azimuth;
    view.elevation = std::isnan(overlay.elevation) ? -20.0 : overlay.elevation;
    view.distance = 1.4 * model->stat.extent;
  }
  mjv_updateScene(model, data, &s.option, nullptr, &view, mjCAT_ALL, &s.scene);

  if (ghost != nullptr) {
    // The moving parts at the ghost's joint positions, translucent green: a colour of no robot
    // (the shipped ones are white, orange and, imported from a URDF, blue).
    const int first = s.scene.ngeom;
    mjv_addGeoms(model, ghost, &s.option, nullptr, mjCAT_DYNAMIC, &s.scene);
    for (int i = first; i < s.scene.ngeom; ++i) {
      mjvGeom& geom = s.scene.geoms[i];
      const float tint[4] = {0.2f, 0.9f, 0.45f, 0.35f};
      std::copy(tint, tint + 4, geom.rgba);
      geom.transparent = 1;
      geom.texid = -1;
      geom.segid = -1;
      geom.label[0] = '\0';
    }
  }
  // Overlay geometry scales with the scene, so that a 0.6 m arm and a 2 m scene both show it.
  const double width_scale = std::clamp(0.012 * model->stat.extent, 0.006, 0.02);
  for (const RenderArrow& arrow : overlay.arrows) {
    const float rgba[4] = {arrow.rgba[0], arrow.rgba[1], arrow.rgba[2], arrow.rgba[3]};
    add_arrow(s.scene, arrow.from, arrow.from + arrow.scale * arrow.vector, width_scale, rgba,
              arrow.label);
  }
  for (const RenderBox& box : overlay.boxes) add_box_edges(s.scene, box, 0.4 * width_scale);
  for (const RenderFrame& frame : overlay.frames) {
    const Eigen::Matrix3d axes = frame.pose.orientation.normalized().toRotationMatrix();
    for (int k = 0; k < 3; ++k) {
      float rgba[4] = {0.1f, 0.1f, 0.1f, frame.alpha};
      rgba[k] = 0.95f;
      add_arrow(s.scene, frame.pose.position, frame.pose.position + frame.length * axes.col(k),
                0.6 * width_scale, rgba, k == 0 ? frame.label : std::string());
    }
  }

  // Caption: MuJoCo's overlay box; its height decides how much of the top the scene leaves free.
  const std::string& caption = overlay.caption;
  const std::size_t line_break = caption.find('\n');
  // mjr_overlay's box adds a margin each side.
  const int text_width = std::max(50, width - 30);
  const std::string title = wrap(caption.substr(0, line_break), s.mjr.charWidthBig, text_width);
  const std::string details = line_break == std::string::npos ? ""
                                                              : wrap(caption.substr(line_break + 1),
                                                                     s.mjr.charWidth, text_width);
  const int title_lines = 1 + static_cast<int>(std::count(title.begin(), title.end(), '\n'));
  const int detail_lines =
      details.empty() ? 0 : 1 + static_cast<int>(std::count(details.begin(), details.end(), '\n'));
  // mjr_overlay's boxes, measured: a line of the big font takes its height + 6 pixels, a line of
  // the normal font its height + 5, a box 14 more.
  const int caption_height =
      caption.empty() ? 0
                      : title_lines * (s.mjr.charHeightBig + 6) + 10 +
                            (detail_lines > 0 ? detail_lines * (s.mjr.charHeight + 5) + 14 : 0);

  if (camera_id < 0) {
    std::vector<Extent> extents;
    for (int i = 0; i < s.scene.ngeom; ++i) {
      const mjvGeom& geom = s.scene.geoms[i];
      // Model geoms (robots, tables, the ghost) by their bounding spheres; the floor plane is
      // endless and not something to frame.
      if (geom.objtype != mjOBJ_GEOM || geom.type == mjGEOM_PLANE || geom.modelrbound <= 0.0f) {
        continue;
      }
      extents.push_back({Eigen::Vector3d(geom.pos[0], geom.pos[1], geom.pos[2]),
                         static_cast<double>(geom.modelrbound)});
    }
    // A label starts at its point and runs to the right: about 0.025 m a character in a picture
    // of a 1-2 m scene, kept in view by a sphere around the point.
    const auto label_radius = [](const std::string& label) { return 0.025 * label.size(); };
    for (const RenderArrow& arrow : overlay.arrows) {
      extents.push_back({arrow.from + arrow.scale * arrow.vector,
                         std::max(3 * width_scale, label_radius(arrow.label))});
    }
    for (const RenderBox& box : overlay.boxes) {
      extents.push_back({0.5 * (box.min + box.max), 0.5 * (box.max - box.min).norm()});
    }
    for (const RenderFrame& frame : overlay.frames) {
      extents.push_back(
          {frame.pose.position + frame.length * (frame.pose.orientation * Eigen::Vector3d::UnitX()),
           std::max(frame.length, label_radius(frame.label))});
    }
    fit_camera(view, extents, model->vis.global.fovy, static_cast<double>(width) / height,
               std::min(0.5, static_cast<double>(caption_height) / height));
    mjv_updateCamera(model, data, &view, &s.scene);
  }

  const mjrRect viewport = {0, 0, width, height};
  mjr_render(viewport, &s.scene, &s.mjr);
  std::vector<unsigned char> rgb(static_cast<std::size_t>(width) * height * 3);
  if (!has_skybox(model)) {
    std::vector<float> depth(static_cast<std::size_t>(width) * height);
    mjr_readPixels(rgb.data(), depth.data(), viewport, &s.mjr);
    paint_sky(rgb, depth, width, height);
    mjr_drawPixels(rgb.data(), nullptr, viewport, &s.mjr);
  }
  if (!caption.empty()) {
    mjr_overlay(mjFONT_BIG, mjGRID_TOPLEFT, viewport, title.c_str(), "", &s.mjr);
    if (!details.empty()) {
      const mjrRect below = {0, 0, width,
                             std::max(1, height - title_lines * s.mjr.charHeightBig - 12)};
      mjr_overlay(mjFONT_NORMAL, mjGRID_TOPLEFT, below, details.c_str(), "", &s.mjr);
    }
  }
  mjr_readPixels(rgb.data(), nullptr, viewport, &s.mjr);

  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = PNG_FORMAT_RGB;
  // OpenGL rows start at the bottom: a negative stride tells libpng so.
  if (png_image_write_to_file(&image, path.c_str(), 0, rgb.data(), -3 * width, nullptr) == 0) {
    const std::string message = image.message;
    png_image_free(&image);
    throw Error("cannot write PNG file '" + path + "': " + message);
  }
}

}  // namespace cartesian_impedance::sim::detail
