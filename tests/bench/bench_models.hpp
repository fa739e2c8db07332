// Models for the strategy and exchange benchmarks, cached as hierarchy files
// under the build tree so only the first run pays for generation and build.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/model_io.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::bench {

inline std::filesystem::path cache_dir() {
  auto dir = std::filesystem::path(TREECUT_BINARY_DIR) / "bench-cache";
  std::filesystem::create_directories(dir);
  return dir;
}

/// A generated model of `points` points (deterministic), built once and cached.
inline std::shared_ptr<const Hierarchy> generated(tools::ModelKind kind, std::size_t points) {
  const auto path = cache_dir() / ("generated-" + std::to_string(static_cast<int>(kind)) + "-" +
                                   std::to_string(points) + ".tch");
  const CacheKey key{points, 1, static_cast<std::uint32_t>(kind)};
  std::string why;
  if (auto h = load_cache(path, key, &why)) return std::make_shared<const Hierarchy>(std::move(*h));
  Hierarchy h = build_from_points(tools::generate_model(kind, points, 1));
  save_cache(h, key, path);
  return std::make_shared<const Hierarchy>(std::move(h));
}

/// The Stanford dragon from ../shared/assets, or null when absent.
inline std::shared_ptr<const Hierarchy> dragon() {
  const auto ply = test::shared_asset("dragon_vrip_normals.ply");
  if (!ply) return nullptr;
  OpenOptions o;
  o.cache_path = cache_dir() / "dragon_vrip_normals.tch";
  return std::make_shared<const Hierarchy>(open_model(*ply, o).hierarchy);
}

/// Points of the large generated cloud: TREECUT_BENCH_POINTS or 20 million.
inline std::size_t large_cloud_points() {
  if (const char* env = std::getenv("TREECUT_BENCH_POINTS")) return std::strtoull(env, nullptr, 10);
  return 20'000'000;
}

}  // namespace treecut::bench
