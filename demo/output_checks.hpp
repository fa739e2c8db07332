// Checks of a command's output files, made before any work so that a
// refused command touches nothing (a user's data is sacred): no output over
// an input or over another output, no file replaced but one of the kind the
// command writes.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace treecut::cli {

/// Whether a file is one this program wrote and can verify whole
/// (is_own_las, is_own_ply, is_own_pcd, is_own_cache...).
using OwnFile = bool (*)(const std::filesystem::path&);

/// OUT may be replaced only when it is treecut's own file of the kind
/// written (OURS: the whole header ours and verified, issue 43): a regular
/// file that is neither a symbolic link (a link is the user's: replacing it
/// would turn it into a file) nor read-only (mode 0444 says keep it).
/// Anything else is an InputError naming WRITTEN (what would go there) or
/// KIND (what the file is not), before any work.
void check_replaceable_output(const std::filesystem::path& out, OwnFile ours,
                              std::string_view written, std::string_view kind);

/// A camera path or scene file treecut wrote: the lines treecut writes
/// first (the format line and treecut's comment) and the whole file parses
/// (a text input, at most 16 MiB).
bool is_own_camera_path(const std::filesystem::path& path);
bool is_own_scene(const std::filesystem::path& path);

/// One command never writes one file twice, nor over a file it reads: an
/// InputError naming the roles (the second of each pair), on the paths as
/// they resolve (`n.ply` and `./d/../n.ply`, links included), whether or not
/// they exist yet.
void check_distinct_files(const std::vector<std::pair<std::filesystem::path, std::string>>& outputs,
                          const std::vector<std::pair<std::filesystem::path, std::string>>& inputs);

}  // namespace treecut::cli
