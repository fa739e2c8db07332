// What the `treecut bench` commands share (bench_common.hpp).
#include "bench_common.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <system_error>

#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::cli {

double walk_part_end(const splat::CameraPath& path, const std::string& path_name, double from,
                     double to) {
  if (path.empty()) throw InputError(path_name + ": the camera path has no keys");
  const double end = to < 0.0 ? path.duration() : to;
  if (!(from >= 0.0) || !(end <= path.duration()) || !(from <= end)) {
    char msg[160];
    std::snprintf(msg, sizeof msg, ": --from %g --to %g is not a part of the path (0 to %.1f s)",
                  from, end, path.duration());
    throw InputError(path_name + msg);
  }
  return end;
}

void check_bench_csv(const std::filesystem::path& csv, std::string_view header,
                     std::string_view what) {
  const std::filesystem::path dir = csv.parent_path();
  if (!dir.empty()) {
    const FileKind k = file_kind(dir);
    if (k != FileKind::Missing && k != FileKind::Directory) {
      throw InputError(quoted_name(dir) + ": " + std::string(describe(k)) +
                       ", not a folder for --csv");
    }
  }
  const FileKind k = file_kind(csv);
  if (k == FileKind::Missing) return;
  if (k != FileKind::Regular) throw InputError(quoted_name(csv) + ": " + std::string(describe(k)));
  const std::string text = read_text_file(csv);
  if (text.rfind(std::string(header) + "\n", 0) != 0) {
    throw InputError(quoted_name(csv) + ": exists and is not a " + std::string(what) +
                     " CSV; not overwritten");
  }
}

void write_bench_csv(const std::filesystem::path& csv, const std::string& text) {
  if (!csv.parent_path().empty()) {
    std::error_code ec;
    std::filesystem::create_directories(csv.parent_path(), ec);
    if (ec) throw std::runtime_error(quoted_name(csv.parent_path()) + ": " + ec.message());
  }
  write_file_atomically(csv, text);
  std::printf("csv       %s\n", csv.string().c_str());
}

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

ScratchCache::ScratchCache(const std::string& stem)
    : path(std::filesystem::temp_directory_path() /
           ("treecut-bench-" + stem + "-" + std::to_string(::getpid()) + ".tch")) {}

ScratchCache::~ScratchCache() {
  // Only a cache treecut wrote: a file of anyone else's that happened to
  // have the name (the bench then failed to write over it) stays.
  if (!is_own_cache(path)) return;
  std::error_code ec;
  std::filesystem::remove(path, ec);
}

}  // namespace treecut::cli
