// treecut view: screenshots (F12/P, the HUD button, a script's `screenshot`).
#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <system_error>

#include "treecut/file_io.hpp"
#include "treecut/splat/image.hpp"
#include "viewer_app.hpp"

namespace treecut::cli {

// What the window shows (scene and HUD), read from the back buffer after the
// HUD is drawn and before the swap.
void Viewer::save_screenshot(const std::string& file, glm::ivec2 size) {
  splat::Image img{size.x, size.y, splat::read_back_rgba(0, GL_BACK, size)};
  for (std::size_t i = 3; i < img.rgba.size(); i += 4) img.rgba[i] = 255;
  // Never over a file the viewer did not write this session: the next free name.
  const std::filesystem::path p = free_screenshot_name(file);
  try {
    if (p.has_parent_path()) {
      std::error_code ec;
      std::filesystem::create_directories(p.parent_path(), ec);
      if (ec) throw std::runtime_error(system_error_text(p.parent_path(), ec.value()));
    }
    splat::write_png(p, img);  // atomic and checked: a failure leaves no partial PNG
  } catch (const std::exception& e) {
    status_ = std::string("screenshot failed: ") + e.what();
    // A scripted run is automation: its failure is the run's (exit code 1,
    // one line); an interactive one reports on the HUD and stderr and goes on.
    if (!script_.empty()) throw std::runtime_error(e.what());
    std::fprintf(stderr, "treecut: error: screenshot %s\n", e.what());
    return;
  }
  written_screenshots_.push_back(p);
  status_ = "saved " + p.string();
  std::printf("screenshot %s\n", p.string().c_str());
}

std::filesystem::path Viewer::free_screenshot_name(const std::filesystem::path& wanted) const {
  auto ours = [&](const std::filesystem::path& p) {
    return std::find(written_screenshots_.begin(), written_screenshots_.end(), p) !=
           written_screenshots_.end();
  };
  if (file_kind(wanted) == FileKind::Missing || ours(wanted)) return wanted;
  for (int i = 1;; ++i) {
    std::filesystem::path p = wanted;
    p.replace_filename(wanted.stem().string() + "-" + std::to_string(i) +
                       wanted.extension().string());
    if (file_kind(p) == FileKind::Missing || ours(p)) return p;
  }
}

}  // namespace treecut::cli
