// Headless EGL: an OpenGL 4.5 core context on an EGL device
// (EGL_EXT_platform_device), with no display and no window. On a machine
// with a GPU that is the GPU's driver (NVIDIA's libEGL_nvidia through
// libglvnd); on Mesa it is the software device (llvmpipe), so the code path
// is tested where there is no GPU. libEGL is opened at run time, like
// libOSMesa: a program that never renders headless does not load it. And the
// choice between the two headless back ends (make_headless_context).
#include <dlfcn.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "mesa_cache.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/gl.hpp"

// Only the types and constants: every function is resolved at run time.
#define EGL_NO_X11
#define MESA_EGL_NO_X11_HEADERS
#include <EGL/egl.h>
#include <EGL/eglext.h>

namespace treecut::splat {
namespace {

struct EglLibrary {
  void* handle = nullptr;
  PFNEGLGETPROCADDRESSPROC get_proc = nullptr;
  PFNEGLQUERYDEVICESEXTPROC query_devices = nullptr;
  PFNEGLQUERYDEVICESTRINGEXTPROC query_device_string = nullptr;
  PFNEGLGETPLATFORMDISPLAYEXTPROC platform_display = nullptr;
  PFNEGLINITIALIZEPROC initialize = nullptr;
  PFNEGLTERMINATEPROC terminate = nullptr;
  PFNEGLQUERYSTRINGPROC query_string = nullptr;
  PFNEGLBINDAPIPROC bind_api = nullptr;
  PFNEGLCHOOSECONFIGPROC choose_config = nullptr;
  PFNEGLCREATECONTEXTPROC create_context = nullptr;
  PFNEGLDESTROYCONTEXTPROC destroy_context = nullptr;
  PFNEGLCREATEPBUFFERSURFACEPROC create_pbuffer = nullptr;
  PFNEGLDESTROYSURFACEPROC destroy_surface = nullptr;
  PFNEGLMAKECURRENTPROC make_current = nullptr;
  PFNEGLGETERRORPROC get_error = nullptr;
  [[nodiscard]] bool complete() const {
    return handle != nullptr && query_devices != nullptr && query_device_string != nullptr &&
           platform_display != nullptr && initialize != nullptr && terminate != nullptr &&
           query_string != nullptr && bind_api != nullptr && choose_config != nullptr &&
           create_context != nullptr && destroy_context != nullptr && create_pbuffer != nullptr &&
           destroy_surface != nullptr && make_current != nullptr && get_error != nullptr;
  }
};

// Opened once per process and never closed: the GL entry points resolved
// through it stay valid for the life of the process.
const EglLibrary& egl_library() {
  static const EglLibrary lib = [] {
    quiet_mesa_shader_cache();
    EglLibrary l;
    for (const char* name : {"libEGL.so.1", "libEGL.so"}) {
      l.handle = dlopen(name, RTLD_NOW | RTLD_LOCAL);
      if (l.handle != nullptr) break;
    }
    if (l.handle == nullptr) return l;
    l.get_proc = reinterpret_cast<PFNEGLGETPROCADDRESSPROC>(dlsym(l.handle, "eglGetProcAddress"));
    if (l.get_proc == nullptr) return l;
    const auto proc = [&l](const char* name) { return l.get_proc(name); };
    l.query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(proc("eglQueryDevicesEXT"));
    l.query_device_string =
        reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(proc("eglQueryDeviceStringEXT"));
    l.platform_display =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(proc("eglGetPlatformDisplayEXT"));
    l.initialize = reinterpret_cast<PFNEGLINITIALIZEPROC>(proc("eglInitialize"));
    l.terminate = reinterpret_cast<PFNEGLTERMINATEPROC>(proc("eglTerminate"));
    l.query_string = reinterpret_cast<PFNEGLQUERYSTRINGPROC>(proc("eglQueryString"));
    l.bind_api = reinterpret_cast<PFNEGLBINDAPIPROC>(proc("eglBindAPI"));
    l.choose_config = reinterpret_cast<PFNEGLCHOOSECONFIGPROC>(proc("eglChooseConfig"));
    l.create_context = reinterpret_cast<PFNEGLCREATECONTEXTPROC>(proc("eglCreateContext"));
    l.destroy_context = reinterpret_cast<PFNEGLDESTROYCONTEXTPROC>(proc("eglDestroyContext"));
    l.create_pbuffer =
        reinterpret_cast<PFNEGLCREATEPBUFFERSURFACEPROC>(proc("eglCreatePbufferSurface"));
    l.destroy_surface = reinterpret_cast<PFNEGLDESTROYSURFACEPROC>(proc("eglDestroySurface"));
    l.make_current = reinterpret_cast<PFNEGLMAKECURRENTPROC>(proc("eglMakeCurrent"));
    l.get_error = reinterpret_cast<PFNEGLGETERRORPROC>(proc("eglGetError"));
    return l;
  }();
  return lib;
}

// EGL 1.5 with EGL_KHR_get_all_proc_addresses resolves core GL functions too.
void* egl_resolve(const char* name) {
  return reinterpret_cast<void*>(egl_library().get_proc(name));
}

bool has_extension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = std::strstr(list, name); p != nullptr; p = std::strstr(p + n, name)) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

std::string egl_error(const EglLibrary& lib, const char* what) {
  char code[16];
  std::snprintf(code, sizeof code, "0x%04x", static_cast<unsigned>(lib.get_error()));
  return std::string("EGL: ") + what + " failed (" + code + ")";
}

}  // namespace

struct EglContext::Impl {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface surface = EGL_NO_SURFACE;  // a pbuffer, unless the display is surfaceless
  std::string device;                   // "software" or "hardware" (EGL_MESA_device_software)
};

EglContext::EglContext(int width, int height)
    : impl_(std::make_unique<Impl>()), width_(width), height_(height) {
  if (width <= 0 || height <= 0) throw gl::GlError("EGL: framebuffer size must be positive");
  const EglLibrary& lib = egl_library();
  if (!lib.complete()) {
    throw gl::GlError("EGL: libEGL.so.1 with EGL_EXT_platform_device not found (install libegl1)");
  }
  EGLDeviceEXT devices[16];
  EGLint count = 0;
  if (lib.query_devices(16, devices, &count) == EGL_FALSE || count <= 0) {
    throw gl::GlError("EGL: no EGL device");
  }
  // The first device that gives a GL 4.5 core context; a GPU's before
  // Mesa's software device, whatever order the loader lists them in.
  std::string why = "EGL: no device gives an OpenGL 4.5 core context";
  for (const bool want_software : {false, true}) {
    for (EGLint i = 0; i < count; ++i) {
      const bool software = has_extension(lib.query_device_string(devices[i], EGL_EXTENSIONS),
                                          "EGL_MESA_device_software");
      if (software != want_software) continue;
      if (try_device(devices[i], why)) {
        impl_->device = software ? "software" : "hardware";
        make_current();
        gl::load("egl", &egl_resolve);
        return;
      }
    }
  }
  throw gl::GlError(why);
}

bool EglContext::try_device(void* device, std::string& why) {
  const EglLibrary& lib = egl_library();
  const EGLDisplay display = lib.platform_display(EGL_PLATFORM_DEVICE_EXT, device, nullptr);
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || lib.initialize(display, &major, &minor) == EGL_FALSE) {
    why = egl_error(lib, "eglInitialize");
    return false;
  }
  const bool surfaceless =
      has_extension(lib.query_string(display, EGL_EXTENSIONS), "EGL_KHR_surfaceless_context");
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE,
                                   surfaceless ? 0 : EGL_PBUFFER_BIT,
                                   EGL_RENDERABLE_TYPE,
                                   EGL_OPENGL_BIT,
                                   EGL_RED_SIZE,
                                   8,
                                   EGL_GREEN_SIZE,
                                   8,
                                   EGL_BLUE_SIZE,
                                   8,
                                   EGL_DEPTH_SIZE,
                                   24,
                                   EGL_NONE};
  EGLConfig config = nullptr;
  EGLint configs = 0;
  if (lib.bind_api(EGL_OPENGL_API) == EGL_FALSE ||
      lib.choose_config(display, config_attribs, &config, 1, &configs) == EGL_FALSE ||
      configs < 1) {
    why = "EGL: no OpenGL config on the device";
    lib.terminate(display);
    return false;
  }
  const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                    4,
                                    EGL_CONTEXT_MINOR_VERSION,
                                    5,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                    EGL_NONE};
  const EGLContext context = lib.create_context(display, config, EGL_NO_CONTEXT, context_attribs);
  if (context == EGL_NO_CONTEXT) {
    why = egl_error(lib, "eglCreateContext (OpenGL 4.5 core)");
    lib.terminate(display);
    return false;
  }
  EGLSurface surface = EGL_NO_SURFACE;
  if (!surfaceless) {
    const EGLint pbuffer_attribs[] = {EGL_WIDTH, width_, EGL_HEIGHT, height_, EGL_NONE};
    surface = lib.create_pbuffer(display, config, pbuffer_attribs);
    if (surface == EGL_NO_SURFACE) {
      why = egl_error(lib, "eglCreatePbufferSurface");
      lib.destroy_context(display, context);
      lib.terminate(display);
      return false;
    }
  }
  impl_->display = display;
  impl_->context = context;
  impl_->surface = surface;
  return true;
}

EglContext::~EglContext() {
  if (!impl_ || impl_->display == EGL_NO_DISPLAY) return;
  const EglLibrary& lib = egl_library();
  lib.make_current(impl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (impl_->surface != EGL_NO_SURFACE) lib.destroy_surface(impl_->display, impl_->surface);
  lib.destroy_context(impl_->display, impl_->context);
  // No eglTerminate: the display is shared by every context made on the
  // device in this process (EGL hands out one display per device), and a
  // later context would find it terminated.
}

void EglContext::make_current() {
  const EglLibrary& lib = egl_library();
  if (lib.make_current(impl_->display, impl_->surface, impl_->surface, impl_->context) ==
      EGL_FALSE) {
    throw gl::GlError(egl_error(lib, "eglMakeCurrent"));
  }
}

const char* EglContext::device_kind() const {
  return impl_->device.c_str();
}

// ---------------------------------------------------------------------------
// The choice of a headless back end.

std::optional<HeadlessGl> parse_headless_gl(std::string_view name) {
  if (name == "auto") return HeadlessGl::Auto;
  if (name == "egl") return HeadlessGl::Egl;
  if (name == "osmesa") return HeadlessGl::Osmesa;
  return std::nullopt;
}

HeadlessGl headless_gl_from_environment() {
  const char* value = std::getenv("TREECUT_GL");
  if (value == nullptr || *value == '\0') return HeadlessGl::Auto;
  if (const auto b = parse_headless_gl(value)) return *b;
  throw gl::GlError(std::string("TREECUT_GL=") + value + ": not auto, egl or osmesa");
}

std::unique_ptr<GlContext> make_headless_context(int width, int height, HeadlessGl backend) {
  if (backend == HeadlessGl::Auto) backend = headless_gl_from_environment();
  if (backend == HeadlessGl::Auto) {
    // A process keeps the back end it loaded first (gl::load).
    if (const char* loaded = gl::loaded_backend()) {
      backend = std::strcmp(loaded, "egl") == 0 ? HeadlessGl::Egl : HeadlessGl::Osmesa;
    }
  }
  switch (backend) {
    case HeadlessGl::Egl:
      return std::make_unique<EglContext>(width, height);
    case HeadlessGl::Osmesa:
      return std::make_unique<OsmesaContext>(width, height);
    case HeadlessGl::Auto:
      break;
  }
  try {
    return std::make_unique<EglContext>(width, height);
  } catch (const gl::GlError&) {
    return std::make_unique<OsmesaContext>(width, height);
  }
}

}  // namespace treecut::splat
