// `treecut bench cache MODELS`: each model opened once (built, caching
// off, or a cache file loaded), then its cache saved and opened REPEAT
// times in this process (the file in the page cache, as a warm open finds
// it): the arrays it decodes to, its size, and the median times. The
// table of docs/benchmarks.md's "Paged cache".
#include "bench_cache.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "bench_common.hpp"
#include "option_checks.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/model_io.hpp"

namespace treecut::cli {

namespace {

struct CacheArgs {
  std::vector<std::string> models;
  int repeat = 5;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void run_bench_cache(const CacheArgs& args) {
  for (const std::string& model : args.models) require_regular_file(model);
  const ScratchCache scratch("cache");
  bool header = false;
  for (const std::string& model : args.models) {
    OpenOptions options;
    options.use_cache = false;
    const Hierarchy h = open_model(model, options).hierarchy;
    // After the first model opens: a malformed one is one line, no table.
    if (!header)
      std::printf(
          "| model | points | nodes | arrays MiB | cache MiB | cache B/point | save s | open s "
          "(median of %d) |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
          args.repeat);
    header = true;
    std::vector<double> save, open;
    for (int i = 0; i < args.repeat; ++i) {
      auto t0 = std::chrono::steady_clock::now();
      save_cache(h, {}, scratch.path);
      save.push_back(seconds_since(t0));
      t0 = std::chrono::steady_clock::now();
      std::string why;
      if (!load_cache(scratch.path, std::nullopt, &why))
        throw std::runtime_error(quoted_name(scratch.path) + ": " + why);
      open.push_back(seconds_since(t0));
    }
    const double bytes = static_cast<double>(std::filesystem::file_size(scratch.path));
    std::printf("| %s | %u | %u | %.1f | %.1f | %.1f | %.3f | %.3f |\n",
                std::filesystem::path(model).filename().c_str(), h.leaf_count(), h.node_count(),
                double(h.memory_bytes()) / (1024.0 * 1024.0), bytes / (1024.0 * 1024.0),
                bytes / std::max(1.0, double(h.leaf_count())), median(save), median(open));
    std::fflush(stdout);
  }
}

}  // namespace

void add_bench_cache_command(CLI::App& bench) {
  auto args = std::make_shared<CacheArgs>();
  auto* cache = bench.add_subcommand(
      "cache",
      "a model's paged cache: its size a point, and the median time to save and to open it "
      "(in the page cache)");
  cache->add_option("MODELS", args->models, "Point files or caches")
      ->check(non_empty_path())
      ->required();
  cache->add_option("-r,--repeat", args->repeat, "Saves and opens per model (median reported)")
      ->check(whole_number(1, 100));
  cache->callback([args] { run_bench_cache(*args); });
}

}  // namespace treecut::cli
