// Writes small hierarchy caches as seeds for cache_fuzz: generated models of a
// few sizes, and every PLY given on the command line that loads with at most
// 300 points (larger seeds slow the fuzzer down). Usage: cache_seeds OUT_DIR [PLY...]
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/generate.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: cache_seeds OUT_DIR [PLY...]\n");
    return 2;
  }
  namespace fs = std::filesystem;
  using namespace treecut;
  using namespace treecut::tools;
  const fs::path out = argv[1];
  fs::create_directories(out);
  const CacheKey key{1234, 5678, 0};
  int written = 0;
  struct Generated {
    ModelKind kind;
    std::size_t points;
    const char* name;
  };
  for (const Generated& g :
       {Generated{ModelKind::Sphere, 1, "sphere-1"}, Generated{ModelKind::Sphere, 2, "sphere-2"},
        Generated{ModelKind::Sphere, 7, "sphere-7"}, Generated{ModelKind::Sphere, 40, "sphere-40"},
        Generated{ModelKind::Terrain, 64, "terrain-64"},
        Generated{ModelKind::City, 120, "city-120"}}) {
    PointSet points = generate_model(g.kind, g.points, 3);
    // The city's cache carries attributes (intensity, classes): the table too is fuzzed.
    if (g.kind == ModelKind::City) treecut::tools::add_survey_attributes(points, g.kind);
    save_cache(build_from_points(std::move(points)), key, out / (std::string(g.name) + ".tch"));
    ++written;
  }
  for (int i = 2; i < argc; ++i) {
    const fs::path ply = argv[i];
    try {
      PointSet points = load_ply(ply);
      if (points.size() > 300) continue;
      save_cache(build_from_points(std::move(points)), key, out / (ply.stem().string() + ".tch"));
      ++written;
    } catch (const InputError&) {
      // Malformed files are seeds for ply_fuzz, not here.
    }
  }
  std::printf("cache_seeds: %d caches in %s\n", written, out.c_str());
  return 0;
}
