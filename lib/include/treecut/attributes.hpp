// Per-point attributes derived from the geometry: normals, splat radii and
// curvature. Parallel over points, deterministic.
#pragma once

#include <cstdint>

#include "treecut/point_set.hpp"

namespace treecut {

struct AttributeOptions {
  int k = 12;                      ///< neighbours for PCA normals, spacing and curvature
  bool recompute_normals = false;  ///< ignore normals from the file
  bool recompute_radii = false;    ///< ignore a radius property from the file
};

/// Fills what is missing: normals (area-weighted from faces, else k-NN PCA
/// oriented outward), radii (face covering radius, else k-NN spacing) and
/// curvature (surface variation of the 1-ring or k-NN covariance). Faces are
/// left in place. Points must be finite.
void complete_attributes(PointSet& points, const AttributeOptions& options = {});

}  // namespace treecut
