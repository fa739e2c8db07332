// Checks of a command's output files (output_checks.hpp).
#include "output_checks.hpp"

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::cli {

// `gen` replaces an output only when it is a file of the kind it writes
// (regenerating is what gen is for), `export` likewise.
void check_replaceable_output(const std::filesystem::path& out, std::string_view magic,
                              std::string_view written, std::string_view kind) {
  const FileKind file = file_kind(out);
  if (file == FileKind::Missing) return;
  if (file != FileKind::Regular)
    throw InputError(quoted_name(out) + ": is " + std::string(describe(file)) +
                     "; refusing to write " + std::string(written) + " there");
  if (!file_starts_with(out, magic))
    throw InputError(quoted_name(out) + ": exists and is not " + std::string(kind) +
                     "; refusing to overwrite it");
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
