// Procedural models the project owns (no external data needed): used by
// `treecut gen`, the default model of the viewer, tests and benchmarks.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut {

enum class ModelKind {
  Sphere,   ///< points on a unit sphere, normals outward, colored by latitude
  Terrain,  ///< a noisy height field (fractal value noise), normals from the field
  City,     ///< a grid of box buildings on a ground plane: heavy occlusion
};

/// "sphere", "terrain", "city" -> kind; throws InputError for anything else.
ModelKind parse_model_kind(std::string_view name);
std::vector<std::string> model_kind_names();

/// Generates exactly `points` points,
/// with exact normals and colors (radii and curvature come from
/// complete_attributes, as for any point cloud); deterministic for a seed. Parallel.
PointSet generate_model(ModelKind kind, std::size_t points, std::uint64_t seed = 1);

}  // namespace treecut
