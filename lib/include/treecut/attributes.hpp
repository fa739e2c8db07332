// Per-point attributes derived from the geometry: normals, splat radii and
// curvature. Parallel over points, deterministic.
#pragma once

#include <cmath>
#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut {

struct AttributeOptions {
  int k = 12;                      ///< neighbours for PCA normals, spacing and curvature
  bool recompute_normals = false;  ///< ignore normals from the file
  bool recompute_radii = false;    ///< ignore a radius property from the file
};

/// How far a point's neighbours are looked for (issue 44): its k nearest
/// within this reach, a few times the model's typical spacing, so that a
/// part of the model holding everything within the reach of its points (a
/// chunk with its halo) gives them the neighbours the whole gives. The
/// spacing is that of the median occupied cell (counted by points) of a
/// grid of 64 cells an axis over the model's box, as on a surface
/// (cell / sqrt(points)), on coarser grids where that cell holds fewer
/// than 16; the reach covers places 16 times sparser. A point with no
/// neighbour within it gets a radius of the reach (capped as isolated
/// points are).
class NeighbourReach {
 public:
  /// The grid over the cube around [LO, HI] (the model's box as its files
  /// declare it: a point outside counts in the nearest cell).
  NeighbourReach(glm::vec3 lo, glm::vec3 hi);
  void count(std::span<const glm::vec3> points);
  /// 4 sqrt(k / pi) spacings; infinite before any point is counted.
  [[nodiscard]] float reach(int k) const;

 private:
  glm::vec3 lo_;
  float cell_;
  std::vector<std::uint32_t> counts_;
};

/// Fills what is missing: normals (area-weighted from faces, else k-NN PCA
/// oriented outward), radii (face covering radius, else k-NN spacing) and
/// curvature (surface variation of the 1-ring or k-NN covariance). Faces are
/// left in place. Points must be finite. REACH: the neighbour search's
/// (NeighbourReach); 0: over the points' own box.
void complete_attributes(PointSet& points, const AttributeOptions& options = {},
                         float reach = 0.0f);

/// A part of a cloud too large to hold (a chunk of the chunked build, issue
/// 44): what only the whole decides, given by the whole.
struct CloudPart {
  glm::vec3 centroid{0.0f};  ///< the whole cloud's: normals face away from it
  /// Points [0, queried) get attributes; the rest are their neighbours only
  /// (the chunk's halo: the points of its neighbours near its border).
  std::size_t queried = 0;
  /// The whole's NeighbourReach: a point's neighbours are all in the part
  /// when it holds everything within this reach of the queried points.
  float reach = INFINITY;
};

/// complete_attributes of a point cloud's part (no faces): normals,
/// radii and curvature of its first PART.queried points, the same values
/// as the whole cloud gives them when the part holds every point within
/// PART.reach of them; but the radii as the neighbours (or the file) give
/// them, not yet completed or capped by the whole's median
/// (finish_part_radii). Returns whether the radii came from the neighbours.
bool complete_part_attributes(PointSet& points, const AttributeOptions& options,
                              const CloudPart& part);

/// What complete_attributes does to a whole cloud's radii once they are
/// all known, with MEDIAN the median of the positive ones over the whole:
/// a missing radius becomes the median; radii FROM_NEIGHBOURS are held to
/// 4 times it (isolated points are not drawn as blobs).
void finish_part_radii(std::vector<float>& radii, float median, bool from_neighbours);

}  // namespace treecut
