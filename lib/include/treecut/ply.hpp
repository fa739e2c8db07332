// PLY import: our own header/body guard in front of OpenMesh's reader.
//
// OpenMesh alone aborts on absurd counts, silently drops rows of a truncated
// ascii body and accepts garbage tokens, so load_ply() validates the header and
// the body size first, reads through OpenMesh, and checks the counts after.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "treecut/point_set.hpp"

namespace treecut {

struct PlyLoadReport {
  std::size_t vertices_in_file = 0;  ///< as the header declares
  std::size_t dropped_nonfinite = 0; ///< points with NaN/inf coordinates, dropped
  std::size_t faces_in_file = 0;     ///< face (or tristrip triangle) count read
  bool had_normals = false;
  bool had_colors = false;
  bool had_radius = false;
};

/// Called with one line per warning (dropped points, ignored elements...).
using WarningSink = std::function<void(const std::string&)>;

/// Loads positions and whatever normals, colors, radii and triangles the file
/// holds. Derives nothing (see attributes.hpp). Throws InputError with one line
/// "PATH: problem" on any malformed input; never allocates more than the file
/// size justifies. Thread-safe (no global state).
PointSet load_ply(const std::filesystem::path& path, PlyLoadReport* report = nullptr,
                  const WarningSink& warn = {});

}  // namespace treecut
