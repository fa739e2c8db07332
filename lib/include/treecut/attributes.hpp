// Per-point attributes derived from the geometry: normals, splat radii and
// curvature. Parallel over points, deterministic.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <vector>

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

/// A part of a cloud too large to hold (a chunk of the chunked build, issue
/// 44): what only the whole decides, given by the whole.
struct CloudPart {
  glm::vec3 centroid{0.0f};  ///< the whole cloud's: normals face away from it
  /// Points [0, queried) get attributes; the rest are their neighbours only
  /// (the chunk's halo: the points of its neighbours near its border).
  std::size_t queried = 0;
};

/// complete_attributes of a point cloud's part (no faces): normals,
/// radii and curvature of its first PART.queried points, the same values
/// as the whole cloud gives them where their neighbours are all in the
/// part; but the radii as the neighbours (or the file) give them, not yet
/// completed or capped by the whole's median (finish_part_radii). REACH
/// (if given) gets each queried point's distance to its k-th neighbour
/// (infinite with fewer), to tell whether its neighbours were all there.
/// Returns whether the radii came from the neighbours.
bool complete_part_attributes(PointSet& points, const AttributeOptions& options,
                              const CloudPart& part, std::vector<float>* reach = nullptr);

/// What complete_attributes does to a whole cloud's radii once they are
/// all known, with MEDIAN the median of the positive ones over the whole:
/// a missing radius becomes the median; radii FROM_NEIGHBOURS are held to
/// 4 times it (isolated points are not drawn as blobs).
void finish_part_radii(std::vector<float>& radii, float median, bool from_neighbours);

}  // namespace treecut
