// What the `treecut bench` commands share: the part of a walk they measure,
// the check of a per-frame CSV target, the median of their figures.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/splat/camera_path.hpp"

namespace treecut::cli {

/// The end of the part [from, to] of a loaded walk (`to` < 0: the walk's
/// end). InputError naming `path_name` for a walk without keys or a part
/// outside it.
[[nodiscard]] double walk_part_end(const splat::CameraPath& path, const std::string& path_name,
                                   double from, double to);

/// Refuses (InputError naming the file) a CSV target that exists and is not
/// an earlier run's CSV (its first line is `header`), or a folder that is not
/// a folder. Creates nothing: the user's files are left alone. `what` names
/// the bench in the message ("bench occlusion").
void check_bench_csv(const std::filesystem::path& csv, std::string_view header,
                     std::string_view what);

/// Writes a bench's CSV (checked before by check_bench_csv): its folder made
/// if missing, the file replaced whole (write_file_atomically), and the
/// "csv       FILE" line printed.
void write_bench_csv(const std::filesystem::path& csv, const std::string& text);

/// A cache of the bench's own in the temporary folder
/// (`treecut-bench-STEM-PID.tch`), removed whatever happens if it is a
/// cache treecut wrote (a user's file of that name is left alone).
struct ScratchCache {
  explicit ScratchCache(const std::string& stem);
  ScratchCache(const ScratchCache&) = delete;
  ScratchCache& operator=(const ScratchCache&) = delete;
  ~ScratchCache();
  std::filesystem::path path;
};

/// The median; NaN for no values.
[[nodiscard]] double median(std::vector<double> v);

}  // namespace treecut::cli
