// Checks of a command's output files (output_checks.hpp).
#include "output_checks.hpp"

#include <sys/stat.h>

#include <cerrno>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/tools/scene_generate.hpp"

namespace treecut::cli {

// `gen` replaces an output only when it is a file of the kind it writes
// and treecut wrote it (regenerating is what gen is for), `export` likewise.
void check_replaceable_output(const std::filesystem::path& out, OwnFile ours,
                              std::string_view written, std::string_view kind) {
  struct stat st {};
  if (::lstat(out.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    throw InputError(system_error_text(out, errno));
  }
  if (S_ISLNK(st.st_mode))
    throw InputError(quoted_name(out) + ": is a symbolic link; refusing to replace it with " +
                     std::string(written) + " (write to the file it names, or remove the link)");
  const FileKind file = file_kind(out);
  if (file != FileKind::Regular)
    throw InputError(quoted_name(out) + ": is " + std::string(describe(file)) +
                     "; refusing to write " + std::string(written) + " there");
  if ((st.st_mode & 0222) == 0)
    throw InputError(quoted_name(out) + ": is read-only; refusing to replace it");
  if (!ours(out))
    throw InputError(quoted_name(out) + ": exists and is not " + std::string(kind) +
                     " treecut wrote; refusing to overwrite it");
}

// The first two lines treecut writes (save_camera_path; gen's scenes),
// then the whole file parses: a user's hand-written path or scene, whose
// lines are not those, is the user's.
bool is_own_camera_path(const std::filesystem::path& path) {
  try {
    if (!file_starts_with(path,
                          "treecut-camera-path 1\n# time eye.x eye.y eye.z target.x "
                          "target.y target.z up.x up.y up.z fov_y_deg\n"))
      return false;
    (void)splat::load_camera_path(path);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

bool is_own_scene(const std::filesystem::path& path) {
  try {
    if (!file_starts_with(path, "treecut-scene 1\n# treecut gen ")) return false;
    SceneParseOptions options;
    options.generator = tools::scene_generator();
    (void)parse_scene_file(path, options);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

// One command never writes one file twice, nor over a file it reads:
// checked before any work, on the paths as they resolve (`n.ply` and
// `./d/../n.ply`, links included), whether or not they exist yet.
void check_distinct_files(
    const std::vector<std::pair<std::filesystem::path, std::string>>& outputs,
    const std::vector<std::pair<std::filesystem::path, std::string>>& inputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j)
      if (same_destination(outputs[i].first, outputs[j].first))
        throw InputError(quoted_name(outputs[i].first) + ": named as both " + outputs[j].second +
                         " and " + outputs[i].second + "; one file cannot hold both");
    for (const auto& [input, role] : inputs)
      if (same_destination(outputs[i].first, input))
        throw InputError(quoted_name(outputs[i].first) + ": is " + role +
                         ", which this command reads; refusing to write " + outputs[i].second +
                         " over it");
  }
}

}  // namespace treecut::cli
