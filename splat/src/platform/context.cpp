#include "treecut/splat/context.hpp"

#include <dlfcn.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>

#include <string>

#include "treecut/splat/gl.hpp"
#include "mesa_cache.hpp"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

namespace treecut::splat {

std::string GlContext::renderer_string() {
  const auto* renderer = reinterpret_cast<const char*>(gl::GetString(GL_RENDERER));
  const auto* version = reinterpret_cast<const char*>(gl::GetString(GL_VERSION));
  return std::string(renderer != nullptr ? renderer : "?") + " / " +
         (version != nullptr ? version : "?");
}

// Mesa keeps compiled shaders in $XDG_CACHE_HOME/mesa_shader_cache (or
// ~/.cache/...); when it cannot make that folder it prints a line of its own
// ("Failed to create ... for shader cache (Permission denied)---disabling")
// beside treecut's one line. Where the folder cannot be made, the cache is
// disabled up front (as Mesa would do anyway), unless the user chose.
void quiet_mesa_shader_cache() {
  if (std::getenv("MESA_SHADER_CACHE_DISABLE") != nullptr ||
      std::getenv("MESA_SHADER_CACHE_DIR") != nullptr ||
      std::getenv("MESA_GLSL_CACHE_DISABLE") != nullptr ||
      std::getenv("MESA_GLSL_CACHE_DIR") != nullptr)
    return;
  std::filesystem::path dir;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && *xdg != '\0')
    dir = xdg;
  else if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0')
    dir = std::filesystem::path(home) / ".cache";
  else
    return;  // Mesa looks the home folder up itself
  std::error_code ec;
  std::filesystem::create_directories(dir / "mesa_shader_cache", ec);
  if (ec || ::access((dir / "mesa_shader_cache").c_str(), W_OK | X_OK) != 0)
    ::setenv("MESA_SHADER_CACHE_DISABLE", "true", 0);
}

// ---------------------------------------------------------------------------
// OSMesa, opened with dlopen. The few declarations from GL/osmesa.h are
// repeated here because including it pulls in GL/gl.h, which clashes with
// glcorearb.h.
namespace {

using OSMesaContextHandle = void*;
using CreateContextAttribsFn = OSMesaContextHandle (*)(const int*, OSMesaContextHandle);
using MakeCurrentFn = unsigned char (*)(OSMesaContextHandle, void*, GLenum, int, int);
using DestroyContextFn = void (*)(OSMesaContextHandle);
using OsmesaProc = void (*)();
using GetProcAddressFn = OsmesaProc (*)(const char*);

constexpr int kOsmesaFormat = 0x22;
constexpr int kOsmesaRgba = 0x1908;
constexpr int kOsmesaDepthBits = 0x30;
constexpr int kOsmesaProfile = 0x33;
constexpr int kOsmesaCoreProfile = 0x34;
constexpr int kOsmesaMajor = 0x36;
constexpr int kOsmesaMinor = 0x37;

struct OsmesaLibrary {
  void* handle = nullptr;
  CreateContextAttribsFn create = nullptr;
  MakeCurrentFn make_current = nullptr;
  DestroyContextFn destroy = nullptr;
  GetProcAddressFn get_proc = nullptr;
};

// Opened once per process and never closed: the GL entry points loaded from it
// stay valid for the life of the process.
const OsmesaLibrary& osmesa_library() {
  static const OsmesaLibrary lib = [] {
    quiet_mesa_shader_cache();
    OsmesaLibrary l;
    for (const char* name : {"libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"}) {
      l.handle = dlopen(name, RTLD_NOW | RTLD_LOCAL);
      if (l.handle != nullptr) break;
    }
    if (l.handle == nullptr) return l;
    l.create =
        reinterpret_cast<CreateContextAttribsFn>(dlsym(l.handle, "OSMesaCreateContextAttribs"));
    l.make_current = reinterpret_cast<MakeCurrentFn>(dlsym(l.handle, "OSMesaMakeCurrent"));
    l.destroy = reinterpret_cast<DestroyContextFn>(dlsym(l.handle, "OSMesaDestroyContext"));
    l.get_proc = reinterpret_cast<GetProcAddressFn>(dlsym(l.handle, "OSMesaGetProcAddress"));
    return l;
  }();
  return lib;
}

void* osmesa_resolve(const char* name) {
  return reinterpret_cast<void*>(osmesa_library().get_proc(name));
}

}  // namespace

struct OsmesaContext::Impl {
  OSMesaContextHandle context = nullptr;
};

OsmesaContext::OsmesaContext(int width, int height)
    : impl_(std::make_unique<Impl>()), width_(width), height_(height) {
  if (width <= 0 || height <= 0) throw gl::GlError("OSMesa: framebuffer size must be positive");
  const OsmesaLibrary& lib = osmesa_library();
  if (lib.handle == nullptr || lib.create == nullptr || lib.make_current == nullptr ||
      lib.destroy == nullptr || lib.get_proc == nullptr) {
    throw gl::GlError("OSMesa: libOSMesa.so.8 not found or incomplete (install libosmesa6)");
  }
  const int attribs[] = {kOsmesaFormat,
                         kOsmesaRgba,
                         kOsmesaDepthBits,
                         24,
                         kOsmesaProfile,
                         kOsmesaCoreProfile,
                         kOsmesaMajor,
                         4,
                         kOsmesaMinor,
                         5,
                         0};
  impl_->context = lib.create(attribs, nullptr);
  if (impl_->context == nullptr) throw gl::GlError("OSMesa: no OpenGL 4.5 core context");
  color_.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 4);
  make_current();
  gl::load("osmesa", &osmesa_resolve);
}

OsmesaContext::~OsmesaContext() {
  if (impl_ && impl_->context != nullptr) osmesa_library().destroy(impl_->context);
}

void OsmesaContext::make_current() {
  if (osmesa_library().make_current(impl_->context, color_.data(), GL_UNSIGNED_BYTE, width_,
                                    height_) == 0) {
    throw gl::GlError("OSMesa: OSMesaMakeCurrent failed");
  }
}

// ---------------------------------------------------------------------------
// GLFW
namespace {

int g_glfw_windows = 0;  // live windows; GLFW is initialised while > 0 (main thread only)
std::string g_glfw_error;

void glfw_error(int code, const char* message) {
  g_glfw_error = "GLFW error " + std::to_string(code) + ": " + (message ? message : "?");
}

void* glfw_resolve(const char* name) {
  return reinterpret_cast<void*>(glfwGetProcAddress(name));
}

}  // namespace

GlfwWindow::GlfwWindow(const WindowOptions& options) {
  if (g_glfw_windows == 0) {
    quiet_mesa_shader_cache();
    glfwSetErrorCallback(&glfw_error);
    if (glfwInit() == GLFW_FALSE)
      throw gl::GlError("GLFW: init failed (no display?) " + g_glfw_error);
  }
  ++g_glfw_windows;
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_DEPTH_BITS, 24);
  window_ =
      glfwCreateWindow(options.width, options.height, options.title.c_str(), nullptr, nullptr);
  if (window_ == nullptr) {
    if (--g_glfw_windows == 0) glfwTerminate();
    throw gl::GlError("GLFW: could not create an OpenGL 4.5 core window. " + g_glfw_error);
  }
  make_current();
  glfwSwapInterval(options.vsync ? 1 : 0);
  try {
    gl::load("glfw", &glfw_resolve);
  } catch (...) {
    glfwDestroyWindow(window_);
    if (--g_glfw_windows == 0) glfwTerminate();
    throw;
  }
}

GlfwWindow::~GlfwWindow() {
  glfwDestroyWindow(window_);
  if (--g_glfw_windows == 0) glfwTerminate();
}

void GlfwWindow::make_current() {
  glfwMakeContextCurrent(window_);
}

glm::ivec2 GlfwWindow::framebuffer_size() const {
  int w = 0;
  int h = 0;
  glfwGetFramebufferSize(window_, &w, &h);
  return {w, h};
}

bool GlfwWindow::should_close() const {
  return glfwWindowShouldClose(window_) != 0;
}
void GlfwWindow::request_close() {
  glfwSetWindowShouldClose(window_, GLFW_TRUE);
}
void GlfwWindow::swap_buffers() {
  glfwSwapBuffers(window_);
}
void GlfwWindow::poll_events() {
  glfwPollEvents();
}

}  // namespace treecut::splat
