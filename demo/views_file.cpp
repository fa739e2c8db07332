// A model's list of views (views_file.hpp).
#include "views_file.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <string>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/splat/camera_path.hpp"

namespace treecut::cli {

ViewSlots read_views(const std::filesystem::path& file) {
  ViewSlots slots;
  struct stat st {};
  if (::lstat(file.c_str(), &st) != 0) {
    if (errno == ENOENT) return slots;
    throw InputError(system_error_text(file, errno));
  }
  const std::string name = quoted_name(file);
  if (S_ISLNK(st.st_mode))
    throw InputError(name + ": is a symbolic link, not treecut's list of views");
  if (!S_ISREG(st.st_mode)) {
    throw InputError(name + ": is " + std::string(describe(file_kind(file))) +
                     ", not treecut's list of views");
  }
  if (!file_starts_with(file, "treecut-camera-path"))
    throw InputError(name + ": exists and is not treecut's list of views");
  // Every line parses, within the text limit; then every key is a slot, once.
  const splat::CameraPath path = splat::load_camera_path(file);
  for (const splat::CameraKey& k : path.keys) {
    const auto slot = static_cast<int>(k.time);
    if (!(slot >= 1 && slot <= 9 && double(slot) == k.time)) {
      char at[32];
      std::snprintf(at, sizeof at, "%.9g", k.time);
      throw InputError(name +
                       ": a camera path whose key times are not the slots 1 to 9 (a key at " + at +
                       " s), not treecut's list of views");
    }
    if (slots[static_cast<std::size_t>(slot - 1)]) {
      throw InputError(name + ": slot " + std::to_string(slot) +
                       " twice, not treecut's list of views");
    }
    slots[static_cast<std::size_t>(slot - 1)] = k.camera;
  }
  return slots;
}

ViewSlots save_view(const std::filesystem::path& file, int slot, const splat::Camera& camera) {
  ViewSlots slots = read_views(file);
  struct stat st {};
  if (::stat(file.c_str(), &st) == 0 && (st.st_mode & 0222) == 0)
    throw InputError(quoted_name(file) + ": is read-only; not replaced");
  slots[static_cast<std::size_t>(slot - 1)] = camera;
  splat::CameraPath path;
  for (int s = 1; s <= 9; ++s) {
    if (const auto& c = slots[static_cast<std::size_t>(s - 1)])
      path.keys.push_back({double(s), *c});
  }
  splat::save_camera_path(file, path);
  return slots;
}

std::filesystem::path views_file_for(const std::filesystem::path& model) {
  const std::filesystem::path named = model.filename().empty() ? model.parent_path() : model;
  return named.string() + ".views";
}

}  // namespace treecut::cli
