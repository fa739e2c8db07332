// The headless GL back end of the commands that draw without a window
// (`render`, `bench occlusion`, `bench scene`): the --gl option and the line
// that says which renderer a report was made on.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "treecut/splat/context.hpp"

namespace treecut::cli {

/// Adds `--gl auto|egl|osmesa` (default auto: TREECUT_GL, else an EGL device,
/// else OSMesa) to a command, into `*value`.
void add_gl_option(CLI::App* command, std::string* value);

/// The context --gl asks for, current on this thread; gl::GlError (one line)
/// when that back end is not available.
[[nodiscard]] std::unique_ptr<splat::GlContext> open_headless(const std::string& gl, int width,
                                                              int height);

/// "GL_RENDERER / GL_VERSION (egl)" of the current context: what every report
/// names as its renderer.
[[nodiscard]] std::string renderer_line(const splat::GlContext& context);

}  // namespace treecut::cli
