// Writes small point files as seeds for points_fuzz: LAS files of generated
// models of a few sizes, with and without colours, at the origin and at map
// coordinates, and text clouds (XYZ, PTS, CSV with a header).
// Usage: points_seeds OUT_DIR
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "treecut/las.hpp"
#include "treecut/pcd.hpp"
#include "treecut/tools/generate.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: points_seeds OUT_DIR\n");
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
  // PCD in its three encodings, with normals, colours and attributes.
  for (const auto& [data, name] :
       {std::pair{PcdData::ascii, "ascii"}, std::pair{PcdData::binary, "binary"},
        std::pair{PcdData::binary_compressed, "compressed"}}) {
    PointSet p = tools::generate_model(tools::ModelKind::City, 30, 3);
    tools::add_survey_attributes(p, tools::ModelKind::City);
    save_pcd(out / ("city-" + std::string(name) + ".pcd"), p, data);
    ++written;
  }
  const char* texts[][2] = {
      {"grid.xyz", "0 0 0\n0.01 0 0\n0 0.01 0\n0.01 0.01 0.002\n"},
      {"colours.xyz",
       "500000.001 5000000.002 100.5 255 0 10\n500000.011 5000000.012 100.5 0 255 20\n"},
      {"normals.xyz", "0 0 0 0 0 1\n1 0 0 0.5 0 0.5\n0 1 0 0 1 0\n"},
      {"scan.pts", "3\n1 2 3 -100 10 20 30\n4 5 6 -90 40 50 60\n7 8 9 -80 70 80 90\n"},
      {"table.csv",
       "X,Y,Z,Intensity,Red,Green,Blue\n1,2,3,9,1,2,3\n4,5,6,8,4,5,6\n7,8,9.5,7,7,8,9\n"},
  };
  for (const auto& [file, text] : texts) {
    std::ofstream seed(out / file, std::ios::binary);
    seed << text;
    seed.close();
    if (!seed) {
      std::fprintf(stderr, "points_seeds: %s: cannot write\n", (out / file).c_str());
      return 1;
    }
    ++written;
  }
  std::printf("points_seeds: %d files in %s\n", written, out.c_str());
  return 0;
}
