// treecut view: camera bookmarks (issue 30). Shift+1..9 keeps the view in a
// slot, 1..9 goes back to it; a model read from a file keeps its slots
// beside it, in `MODEL.views` (views_file.hpp), read when the model opens.
// That file is written only when it is missing or reads whole as treecut's
// list of views: never over a file of the user's.
#include <imgui.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "messages.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "viewer_app.hpp"
#include "views_file.hpp"

namespace treecut::cli {

std::filesystem::path Viewer::bookmarks_file() const {
  if (current_file_.empty()) return {};  // a generated model: slots for this session only
  return views_file_for(current_file_);
}

void Viewer::load_bookmarks() {
  bookmarks_.fill(std::nullopt);
  const std::filesystem::path file = bookmarks_file();
  if (file.empty()) return;
  try {
    bookmarks_ = read_views(file);
  } catch (const std::exception& e) {
    // Not a list of views: said in the HUD, and the viewer goes on without
    // them; a save is then the failure, in its one line on stderr.
    say(std::string(e.what()) + " (bookmarks not read)");
  }
}

void Viewer::save_bookmark(int slot) {
  bookmarks_[static_cast<std::size_t>(slot - 1)] = camera_;
  const std::filesystem::path file = bookmarks_file();
  if (file.empty()) {
    say("view " + std::to_string(slot) + " kept (a generated model: not saved)");
    return;
  }
  try {
    try {
      bookmarks_ = save_view(file, slot, camera_);
    } catch (const InputError& e) {
      const std::string what = e.what();
      throw std::runtime_error(what.ends_with("not replaced") ? what : what + "; not replaced");
    }
    say("view " + std::to_string(slot) + " saved in " + file.filename().string());
    std::printf("bookmark  %d saved in %s\n", slot, quoted_name(file).c_str());
  } catch (const std::exception& e) {
    say(std::string("bookmark not saved: ") + e.what());
    if (!script_.empty()) throw;
    print_error(e.what());
  }
}

void Viewer::go_to_bookmark(int slot) {
  const auto& c = bookmarks_[static_cast<std::size_t>(slot - 1)];
  if (!c) {
    say("no view " + std::to_string(slot) + " (Shift+" + std::to_string(slot) + " keeps one)");
    return;
  }
  const float near_plane = camera_.near_plane, far_plane = camera_.far_plane;
  camera_ = *c;
  camera_.near_plane = near_plane, camera_.far_plane = far_plane;  // fitted each frame
  say("view " + std::to_string(slot));
}

// The HUD's bookmarks: a button per slot kept, to go back there.
void Viewer::bookmarks_panel() {
  ImGui::TextDisabled("Shift+1..9 keeps the view, 1..9 goes back");
  bool any = false;
  for (int s = 1; s <= 9; ++s) {
    if (!bookmarks_[static_cast<std::size_t>(s - 1)]) continue;
    if (any) ImGui::SameLine();
    any = true;
    if (ImGui::Button(std::to_string(s).c_str())) go_to_bookmark(s);
  }
  if (!any) ImGui::TextUnformatted("none yet");
}

}  // namespace treecut::cli
