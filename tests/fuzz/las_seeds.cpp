// Writes small LAS files as seeds for las_fuzz: generated models of a few
// sizes, with and without colours, at the origin and at map coordinates.
// Usage: las_seeds OUT_DIR
#include <cstdio>
#include <filesystem>
#include <string>

#include "treecut/las.hpp"
#include "treecut/tools/generate.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: las_seeds OUT_DIR\n");
    return 2;
  }
  namespace fs = std::filesystem;
  using namespace treecut;
  const fs::path out = argv[1];
  fs::create_directories(out);
  int written = 0;
  for (const std::size_t n : {1, 7, 40}) {
    for (const bool colours : {false, true}) {
      for (const bool map : {false, true}) {
        PointSet p = tools::generate_model(tools::ModelKind::Sphere, n, 3);
        if (!colours) p.colors.clear();
        if (map) p.frame.origin = glm::dvec3(500000.0, 5000000.0, 100.0);
        save_las(out / ("sphere-" + std::to_string(n) + (colours ? "-rgb" : "") +
                        (map ? "-utm" : "") + ".las"),
                 p);
        ++written;
      }
    }
  }
  std::printf("las_seeds: %d files in %s\n", written, out.c_str());
  return 0;
}
