#include "renderer.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <dlfcn.h>
#include <png.h>

#include <algorithm>
#include <cstdio>
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

void Renderer::render_png(mjModel* model, mjData* data, const std::string& path, int width,
                          int height, int camera_id) {
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
    mjr_makeContext(model, &s.mjr, mjFONTSCALE_100);
    mjv_defaultScene(&s.scene);
    mjv_makeScene(model, &s.scene, 2000);
    s.made = true;
  }
  mjr_setBuffer(mjFB_OFFSCREEN, &s.mjr);
  if (s.mjr.currentBuffer != mjFB_OFFSCREEN) {
    throw Error("the OpenGL context has no offscreen framebuffer");
  }

  mjvCamera view;
  mjv_defaultFreeCamera(model, &view);
  if (camera_id >= 0) {
    view.type = mjCAMERA_FIXED;
    view.fixedcamid = camera_id;
  } else {
    // From the robot's right side, a little to the front (it faces +x, so tables in front of it
    // do not hide it), slightly above, framing the model's extent (the floor plane does not
    // count) around its centre.
    view.azimuth = 105.0;
    view.elevation = -20.0;
    view.distance = 1.4 * model->stat.extent;
  }
  mjv_updateScene(model, data, &s.option, nullptr, &view, mjCAT_ALL, &s.scene);
  const mjrRect viewport = {0, 0, width, height};
  mjr_render(viewport, &s.scene, &s.mjr);
  std::vector<unsigned char> rgb(static_cast<std::size_t>(width) * height * 3);
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
