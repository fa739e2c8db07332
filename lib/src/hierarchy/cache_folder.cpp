// The cache folder as a user sees it (cache_folder.hpp).
#include "treecut/cache_folder.hpp"

#include <fcntl.h>
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <system_error>

#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

std::filesystem::path default_cache_folder() {
  // The XDG base-directory rules: a relative XDG_CACHE_HOME is invalid and
  // ignored (it would put caches wherever the program was started).
  if (const char* xdg = std::getenv("XDG_CACHE_HOME");
      xdg && *xdg && std::filesystem::path(xdg).is_absolute())
    return std::filesystem::path(xdg) / "treecut";
  if (const char* home = std::getenv("HOME"); home && *home)
    return std::filesystem::path(home) / ".cache" / "treecut";
  // No home at all: the temporary folder, if there is a usable one.
  std::error_code ec;
  const std::filesystem::path tmp = std::filesystem::temp_directory_path(ec);
  if (ec || !tmp.is_absolute()) return {};
  return tmp / "treecut";
}

std::vector<CacheFileInfo> list_caches(const std::filesystem::path& folder) {
  std::vector<CacheFileInfo> out;
  std::error_code ec;
  if (!std::filesystem::exists(folder, ec)) return out;
  std::filesystem::directory_iterator it(folder, ec);
  if (ec) throw std::runtime_error(quoted_name(folder) + ": " + ec.message());
  for (const std::filesystem::directory_entry& e : it) {
    const std::filesystem::path& p = e.path();
    if (p.extension() != ".tch" || !e.is_regular_file(ec) || !is_own_cache(p)) continue;
    CacheFileInfo info;
    info.file = p;
    info.bytes = e.file_size(ec);
    info.last_used = e.last_write_time(ec);
    // NAME-HASH.tch (default_cache_path): the model's name before the hash.
    const std::string stem = p.stem().string();
    const auto dash = stem.rfind('-');
    info.model =
        dash != std::string::npos && stem.size() - dash == 17 ? stem.substr(0, dash) : stem;
    out.push_back(std::move(info));
  }
  std::sort(out.begin(), out.end(), [](const CacheFileInfo& a, const CacheFileInfo& b) {
    return a.last_used != b.last_used ? a.last_used > b.last_used : a.file < b.file;
  });
  return out;
}

void mark_cache_used(const std::filesystem::path& cache) noexcept {
  // The kernel's clock, as a write's: a cache written after this one is
  // never older than it (the library clock runs ahead of the file system's
  // coarse one).
  const timespec times[2] = {{0, UTIME_OMIT}, {0, UTIME_NOW}};
  (void)::utimensat(AT_FDCWD, cache.c_str(), times, 0);
}

std::vector<CacheFileInfo> caches_over_limit(std::span<const CacheFileInfo> caches,
                                             std::uint64_t max_bytes,
                                             const std::filesystem::path& keep) {
  std::uint64_t total = 0;
  for (const CacheFileInfo& c : caches) total += c.bytes;
  std::vector<CacheFileInfo> out;
  // From the least recently used end, skipping the one to keep.
  for (auto it = caches.rbegin(); it != caches.rend() && total > max_bytes; ++it) {
    if (!keep.empty() && it->file == keep) continue;
    out.push_back(*it);
    total -= it->bytes;
  }
  return out;
}

std::vector<std::string> remove_caches(std::span<const CacheFileInfo> caches) {
  std::vector<std::string> failures;
  for (const CacheFileInfo& c : caches) {
    // Checked again just before: a file put there meanwhile is not ours.
    if (!is_own_cache(c.file)) continue;
    std::error_code ec;
    std::filesystem::remove(c.file, ec);
    if (ec) failures.push_back(quoted_name(c.file) + ": " + ec.message());
  }
  return failures;
}

std::optional<std::uint64_t> parse_byte_size(const std::string& text) {
  // Decimal digits with an optional fraction, then the unit: strtod would
  // read "0x10" as sixteen and "nan" and "inf" as numbers.
  std::size_t digits = 0;
  while (digits < text.size() &&
         (std::isdigit(static_cast<unsigned char>(text[digits])) || text[digits] == '.'))
    ++digits;
  if (digits == 0 ||
      std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(digits), '.') > 1)
    return std::nullopt;
  double v = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + digits, v);
  if (ec != std::errc() || end != text.data() + digits || !std::isfinite(v)) return std::nullopt;
  std::string unit(text.substr(digits));
  if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
  if (unit.size() > 1 && (unit.back() == 'i')) unit.pop_back();  // 2GiB, 2Gi
  double scale = 1.0;
  if (unit.size() == 1) {
    switch (std::toupper(static_cast<unsigned char>(unit[0]))) {
      case 'K':
        scale = 1024.0;
        break;
      case 'M':
        scale = 1024.0 * 1024.0;
        break;
      case 'G':
        scale = 1024.0 * 1024.0 * 1024.0;
        break;
      case 'T':
        scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
        break;
      default:
        return std::nullopt;
    }
  } else if (!unit.empty()) {
    return std::nullopt;
  }
  const double bytes = v * scale;
  if (bytes >= 1.8e19) return std::nullopt;
  return static_cast<std::uint64_t>(bytes);
}

std::uint64_t cache_size_limit() {
  constexpr std::uint64_t kDefault = std::uint64_t{20} << 30;
  const char* env = std::getenv("TREECUT_CACHE_LIMIT");
  if (env == nullptr || *env == '\0') return kDefault;
  const std::optional<std::uint64_t> v = parse_byte_size(env);
  if (!v) {
    throw InputError(std::string("TREECUT_CACHE_LIMIT: '") + env +
                     "' is not a size (bytes, or with K, M, G or T; 0 for no limit)");
  }
  return *v == 0 ? UINT64_MAX : *v;
}

}  // namespace treecut
