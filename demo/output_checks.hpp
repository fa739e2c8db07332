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

/// OUT may be replaced only when it is a file of the kind written: one that
/// starts with MAGIC. A directory, a FIFO or any other file is an InputError
/// naming WRITTEN (what would go there) or KIND (what the file is not).
void check_replaceable_output(const std::filesystem::path& out, std::string_view magic,
                              std::string_view written, std::string_view kind);

/// One command never writes one file twice, nor over a file it reads: an
/// InputError naming the roles (the second of each pair), on the paths as
/// they resolve (`n.ply` and `./d/../n.ply`, links included), whether or not
/// they exist yet.
void check_distinct_files(const std::vector<std::pair<std::filesystem::path, std::string>>& outputs,
                          const std::vector<std::pair<std::filesystem::path, std::string>>& inputs);

}  // namespace treecut::cli
