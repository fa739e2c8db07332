#include "headless_gl.hpp"

#include "treecut/splat/gl.hpp"

namespace treecut::cli {

void add_gl_option(CLI::App* command, std::string* value) {
  command
      ->add_option("--gl", *value,
                   "Headless GL: auto (TREECUT_GL, else an EGL device, else OSMesa), egl, osmesa")
      ->check(CLI::IsMember({"auto", "egl", "osmesa"}))
      ->capture_default_str();
}

std::unique_ptr<splat::GlContext> open_headless(const std::string& gl, int width, int height) {
  const auto backend = splat::parse_headless_gl(gl);
  if (!backend) throw gl::GlError("--gl " + gl + ": not auto, egl or osmesa");
  return splat::make_headless_context(width, height, *backend);
}

std::string renderer_line(const splat::GlContext& context) {
  std::string line = splat::GlContext::renderer_string() + " (" + context.backend();
  if (const auto* egl = dynamic_cast<const splat::EglContext*>(&context)) {
    line += std::string(", ") + egl->device_kind() + " device";
  }
  return line + ")";
}

}  // namespace treecut::cli
