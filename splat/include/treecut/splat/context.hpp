// GL context back ends: one renderer, three ways to get an OpenGL 4.5 core
// context. Headless, with no display: EglContext on an EGL device (a GPU's
// driver, or Mesa's software device) and OsmesaContext (llvmpipe on the
// CPU); make_headless_context() chooses between them for tests, benchmarks
// and `treecut render` (--gl, TREECUT_GL). GlfwWindow is a real window for
// `treecut view` (under Xvfb in CI).
//
// Constructing a context makes it current on the calling thread and loads the
// GL entry points (gl.hpp); that thread is the render thread from then on.
// A process uses one back end only (see gl::load). Not copyable, not movable:
// the GL objects made in a context refer to it.
#pragma once

#include <glm/vec2.hpp>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

struct GLFWwindow;

namespace treecut::splat {

class GlContext {
 public:
  GlContext() = default;
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;
  virtual ~GlContext() = default;

  /// Makes the context current on the calling thread.
  virtual void make_current() = 0;
  /// Size of the default framebuffer in pixels.
  [[nodiscard]] virtual glm::ivec2 framebuffer_size() const = 0;
  /// "egl", "osmesa" or "glfw".
  [[nodiscard]] virtual const char* backend() const = 0;
  /// GL_RENDERER / GL_VERSION of the current context, for logs and reports.
  [[nodiscard]] static std::string renderer_string();
};

/// An offscreen OSMesa context of the given default-framebuffer size. libOSMesa
/// is opened at run time (dlopen), so programs that never render headless do
/// not load it next to libGL. Throws gl::GlError when OSMesa or GL 4.5 core is
/// unavailable.
class OsmesaContext final : public GlContext {
 public:
  OsmesaContext(int width, int height);
  ~OsmesaContext() override;
  void make_current() override;
  [[nodiscard]] glm::ivec2 framebuffer_size() const override { return {width_, height_}; }
  [[nodiscard]] const char* backend() const override { return "osmesa"; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int width_ = 0;
  int height_ = 0;
  std::vector<unsigned char> color_;  // the OSMesa default framebuffer (unused by the renderer)
};

/// A headless context on an EGL device (EGL_EXT_platform_device): the first
/// device that gives OpenGL 4.5 core, a GPU's before Mesa's software device.
/// Surfaceless where the display allows it, else a pbuffer of the given
/// size (the renderer draws into its own framebuffers). libEGL is opened at
/// run time. Throws gl::GlError when there is no such device.
class EglContext final : public GlContext {
 public:
  EglContext(int width, int height);
  ~EglContext() override;
  void make_current() override;
  [[nodiscard]] glm::ivec2 framebuffer_size() const override { return {width_, height_}; }
  [[nodiscard]] const char* backend() const override { return "egl"; }
  /// "hardware", or "software" for Mesa's device (EGL_MESA_device_software).
  [[nodiscard]] const char* device_kind() const;

 private:
  struct Impl;
  bool try_device(void* device, std::string& why);
  std::unique_ptr<Impl> impl_;
  int width_ = 0;
  int height_ = 0;
};

/// Which headless back end: Auto takes TREECUT_GL when it is set, else the
/// back end this process already loaded, else EGL when a device gives GL 4.5
/// core, else OSMesa.
enum class HeadlessGl { Auto, Egl, Osmesa };

/// "auto", "egl", "osmesa"; nullopt otherwise.
[[nodiscard]] std::optional<HeadlessGl> parse_headless_gl(std::string_view name);
/// TREECUT_GL (unset or empty: Auto); gl::GlError for another value.
[[nodiscard]] HeadlessGl headless_gl_from_environment();
/// A headless context of that size, current on the calling thread. Throws
/// gl::GlError when the back end asked for is not available.
[[nodiscard]] std::unique_ptr<GlContext> make_headless_context(
    int width, int height, HeadlessGl backend = HeadlessGl::Auto);

struct WindowOptions {
  int width = 1280;
  int height = 720;
  std::string title = "treecut";
  bool vsync = false;  ///< off: the viewer measures the renderer, not the display
};

/// A GLFW window with a GL 4.5 core context. Initialises GLFW on first use and
/// terminates it with the last window. Throws gl::GlError without a display.
class GlfwWindow final : public GlContext {
 public:
  explicit GlfwWindow(const WindowOptions& options);
  ~GlfwWindow() override;
  void make_current() override;
  [[nodiscard]] glm::ivec2 framebuffer_size() const override;
  [[nodiscard]] const char* backend() const override { return "glfw"; }

  [[nodiscard]] GLFWwindow* handle() const { return window_; }
  [[nodiscard]] bool should_close() const;
  void request_close();
  void swap_buffers();
  /// Processes pending window events (input callbacks run here).
  static void poll_events();

 private:
  GLFWwindow* window_ = nullptr;
};

}  // namespace treecut::splat
