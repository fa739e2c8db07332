// treecut view: screenshots (F12/P, the HUD button, a script's `screenshot`).
#include <cstdio>
#include <stdexcept>
#include <system_error>

#include "messages.hpp"
#include "treecut/file_io.hpp"
#include "treecut/splat/image.hpp"
#include "viewer_app.hpp"

namespace treecut::cli {

// The scene alone (read from the back buffer before the HUD is drawn, or
// drawn again at another size) or the window with its HUD (read after it),
// before the swap.
void Viewer::save_screenshot(const std::string& file, glm::ivec2 size) {
  // At another size than the window: the scene alone, drawn again there.
  const glm::ivec2 wanted_size =
      screenshot_size_.x > 0 ? screenshot_size_ : size * (1 << screenshot_scale_index_);
  splat::Image img = !screenshot_hud_ && wanted_size != size
                         ? draw_at(wanted_size)
                         : splat::Image{size.x, size.y, splat::read_back_rgba(0, GL_BACK, size)};
  size = glm::ivec2(img.width, img.height);
  for (std::size_t i = 3; i < img.rgba.size(); i += 4) img.rgba[i] = 255;
  std::filesystem::path p;
  try {
    const std::filesystem::path wanted = file;
    if (wanted.has_parent_path()) {
      std::error_code ec;
      std::filesystem::create_directories(wanted.parent_path(), ec);
      if (ec) throw std::runtime_error(system_error_text(wanted.parent_path(), ec.value()));
    }
    // Never over an existing file, not even a shot of this session (a script
    // taking `screenshot b.png` four times leaves b.png, b-1.png, b-2.png,
    // b-3.png): the name is chosen as the file is committed, atomically.
    std::string bytes;
    try {
      bytes = splat::encode_png(img);
    } catch (const std::exception& e) {
      throw std::runtime_error(quoted_name(wanted) + ": " + e.what());
    }
    p = write_file_to_free_name(wanted, bytes);
  } catch (const std::exception& e) {
    say(std::string("screenshot failed: ") + e.what());
    // A scripted run is automation: its failure is the run's (exit code 1,
    // one line); an interactive one reports on the HUD and stderr and goes on.
    if (!script_.empty()) throw std::runtime_error(e.what());
    print_error(std::string("screenshot ") + e.what());
    return;
  }
  say("saved " + p.filename().string());
  if (screenshot_hud_ && show_hud_) {
    // What the HUD covers, for whoever checks it stays out of the way.
    std::printf("screenshot %s (HUD %dx%d of %dx%d)\n", quoted_name(p).c_str(), hud_size_.x,
                hud_size_.y, size.x, size.y);
  } else {
    std::printf("screenshot %s\n", quoted_name(p).c_str());
  }
}

splat::Image Viewer::draw_at(glm::ivec2 size) {
  const glm::ivec2 window = renderer_->size();
  renderer_->resize(size);
  // No queries in this extra draw: the frame loop sets its hook again.
  renderer_->set_query_hook(nullptr);
  if (frame_loop_->drawing_scene()) {
    renderer_->draw_scene(frame_loop_->scene_cut(), camera_, settings_, true);
  } else {
    renderer_->draw(frame_loop_->cut(), camera_, settings_, true);
  }
  splat::Image img{size.x, size.y, renderer_->read_pixels()};
  renderer_->resize(window);
  return img;
}

}  // namespace treecut::cli
