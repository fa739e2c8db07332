// treecut cache: the cache folder as a user sees it (issue 30): the caches
// with their size, last use and model, and their removal (all, those not
// used for some days, or the least recently used down to a size). Only
// treecut's caches are listed or removed (treecut/cache_folder.hpp).
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "messages.hpp"
#include "option_checks.hpp"
#include "treecut/cache_folder.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::cli {
namespace {

struct CacheArgs {
  std::string folder;  // default: default_cache_folder()
  bool clear = false;
  double older_than_days = -1.0;
  std::string max_size;
};

std::string megabytes(std::uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f MB", double(bytes) / 1e6);
  return text;
}

std::string local_time(std::filesystem::file_time_type t) {
  const auto sys = std::chrono::file_clock::to_sys(t);
  const std::time_t tt = std::chrono::system_clock::to_time_t(sys);
  std::tm tm{};
  localtime_r(&tt, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M", &tm);
  return text;
}

void run_cache(const CacheArgs& a) {
  const std::filesystem::path folder =
      a.folder.empty() ? default_cache_folder() : std::filesystem::path(a.folder);
  if (folder.empty()) throw std::runtime_error("no cache folder (HOME and XDG_CACHE_HOME unset)");
  std::optional<std::uint64_t> max_size;
  if (!a.max_size.empty()) max_size = parse_byte_size(a.max_size);
  if (const FileKind kind = file_kind(folder);
      kind != FileKind::Missing && kind != FileKind::Directory) {
    throw InputError(quoted_name(folder) + ": is " + std::string(describe(kind)) +
                     ", not a cache folder");
  }
  std::vector<CacheFileInfo> caches = list_caches(folder);
  std::vector<CacheFileInfo> remove;
  if (a.clear) {
    remove = caches;
  } else {
    if (a.older_than_days >= 0.0) {
      // Each cache's age in days, in double: a cut-off of now less 60,000
      // days overflowed the clock and made every cache old.
      const auto now = std::filesystem::file_time_type::clock::now();
      for (const CacheFileInfo& c : caches) {
        const double days =
            std::chrono::duration<double, std::ratio<86400>>(now - c.last_used).count();
        if (days > a.older_than_days) remove.push_back(c);
      }
    }
    if (max_size) {
      // What is left after the old ones go, least recently used first.
      std::vector<CacheFileInfo> left;
      for (const CacheFileInfo& c : caches) {
        bool going = false;
        for (const CacheFileInfo& r : remove) going = going || r.file == c.file;
        if (!going) left.push_back(c);
      }
      for (const CacheFileInfo& c : caches_over_limit(left, *max_size)) remove.push_back(c);
    }
  }
  const std::vector<std::string> failed = remove_caches(remove);
  for (const CacheFileInfo& c : remove) {
    bool kept = false;
    for (const std::string& f : failed) kept = kept || f.rfind(quoted_name(c.file), 0) == 0;
    if (!kept)
      std::printf("removed   %s (%s)\n", quoted_name(c.file).c_str(), megabytes(c.bytes).c_str());
  }
  caches = list_caches(folder);
  std::uint64_t total = 0;
  for (const CacheFileInfo& c : caches) total += c.bytes;
  std::printf("%s: %zu cache(s), %s\n", quoted_name(folder).c_str(), caches.size(),
              megabytes(total).c_str());
  for (const CacheFileInfo& c : caches) {
    // Names as messages show them: a name with a newline or an escape
    // sequence cannot break the listing or drive the terminal.
    std::printf("  %10s  %s  %s  (%s)\n", megabytes(c.bytes).c_str(),
                local_time(c.last_used).c_str(), quoted_name(c.model).c_str(),
                quoted_name(c.file.filename().string()).c_str());
  }
  if (!failed.empty()) {
    for (const std::string& f : failed) print_error(f);
    throw std::runtime_error(std::to_string(failed.size()) + " cache(s) could not be removed");
  }
}

}  // namespace

void add_cache_command(CLI::App& app) {
  auto args = std::make_shared<CacheArgs>();
  auto* cmd = app.add_subcommand(
      "cache", "List the hierarchy caches (size, last use, model) and remove them");
  cmd->add_option("--folder", args->folder,
                  "The cache folder (default: $XDG_CACHE_HOME/treecut or ~/.cache/treecut)")
      ->check(non_empty_path());
  cmd->add_flag("--clear", args->clear, "Remove every cache");
  cmd->add_option("--older-than", args->older_than_days,
                  "Remove the caches not used for this many days")
      ->check(finite_number(0.0, 1e6));
  cmd->add_option("--max-size", args->max_size,
                  "Remove the least recently used caches until the rest fit (e.g. 5G, 500M)")
      ->check(CLI::Validator(
          [](const std::string& v) {
            return parse_byte_size(v) ? std::string()
                                      : "'" + v + "' is not a size (bytes, or with K, M, G or T)";
          },
          "SIZE"));
  cmd->callback([args] { run_cache(*args); });
}

}  // namespace treecut::cli
