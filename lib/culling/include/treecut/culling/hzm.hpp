// Occlusion culling of many objects with a hierarchical Z-map (HZM):
// Peng & Cao, "Integrating Occlusion Culling and Parallel LOD for Rendering
// Complex 3D Environments on GPU", I3D 2013
// (../shared/papers/occlusion-culling-with-parallel-lod.txt), section 6,
// on the CPU cores (a WorkerPool) instead of CUDA.
//
// Preprocess (section 6.1): each object's compactness (Eq. 2) and the
// candidate occluder set (COS): the objects of compactness >= CT that have
// an inner box, sorted by compactness, highest first.
//
// Per frame (sections 6.2, 6.3), each phase data-parallel over objects:
//   1. project: every object's AABB to its clipped screen rectangle and
//      nearest depth; frustum culling (the paper tests the AABB against the
//      frustum).
//   2. select: Eq. 3 weight of the candidates in the frustum,
//      weight = V |N . E| / D (V the AABB's volume, N the normal of the OBB's
//      largest face, E the viewing direction, D the distance from the eye to
//      the AABB), and the active occluder set (AOS): the `active` highest
//      weights (a fixed size, as the paper's). A candidate whose AABB crosses
//      the near plane or contains the eye is not taken (added: its depth
//      cannot be drawn conservatively without the near plane's clipping).
//   3. build: the occluders' depth rasterized into a small depth image (one
//      cell = s x s pixels, s chosen so that the larger side has
//      `depth_width` cells), then the hierarchical Z-map by max-reduction of
//      2 x 2 cells (level 0 the depth image, each level half the size, the
//      last 1 x 1).
//   4. test: every object in the frustum is occluded when its nearest
//      depth D_i lies behind every HZM cell its rectangle touches at the
//      level of Eq. 5 (below), else potentially visible; added: one that
//      test keeps is tested again `finer_levels` levels finer; added: the
//      occluders are tested too (the paper takes them as visible), and one
//      that the others hide is culled (sound: hzm_pyramid.cpp, test()).
//
// Why it is conservative (an object the exact reference sees is never
// culled). The reference: every object's box drawn at full resolution,
// sampled at pixel centers, front-most wins (reference_visibility()). An
// occluder writes a cell only where its inner box covers the cell's sample
// points, and writes the largest eye depth of the inner box's front surface
// at them. One pixel a cell: the sample is the pixel center (exact). Larger
// cells: the four corners of the cell (kept within the viewport's extreme
// pixel centers), shared with the neighbours.
//   - Covered: the box's silhouette is convex, so it contains the square the
//     corners span and every pixel center of the cell in it.
//   - Depth: the front surface of a convex body, as eye depth over the
//     screen, is a monotone function of a convex function (the projective
//     map (x, y, z) -> (x/z, y/z, -1/z) keeps the body convex and the entry
//     point is the lowest point of its vertical line), so over the cell it
//     is largest at a corner: every pixel center of the cell sees the inner
//     box, hence the object, at most that deep. The inner box lies inside
//     the object's solid, so a ray reaching it has hit the object before.
//   - The z-buffer keeps the smallest of the occluders' values and the
//     reduction the largest of 2 x 2 cells, so every HZM cell bounds from
//     above the depth of the front-most occluder at every pixel center under
//     it.
//   - An object's AABB contains its box, its rectangle every pixel center
//     the box covers, and its depth D_i is <= every point of it: if D_i is
//     behind all the cells under the rectangle, an occluder is in front of
//     it at every pixel center it could cover.
// A small relative margin (kDepthMargin) absorbs float rounding of the two
// computations. An object crossing the near plane is never culled.
//
// Eq. 5 as printed in our copy of the paper is garbled; what it states is
// the level at which the bounding square (side R cells at level 0) "is
// guaranteed in a range of pixel size of (1, 4)": the finest level whose
// cells are at least R wide, level = ceil(log2 R) counted from the finest
// (the paper counts from the coarsest, L - that), where the rectangle
// touches at most 2 x 2 cells.
//
// The exact reference here is on the CPU (ray casting every object's box
// at every pixel center of its rectangle into an id buffer); the issue's
// reference, the GL renderer's id buffer, comes when scenes reach the
// renderer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/vec3.hpp>
#include <optional>
#include <span>
#include <vector>

#include "treecut/culling/many_objects.hpp"

namespace treecut::culling {

/// Eq. 2: how well points fill their oriented box, from their orthogonal
/// projections along the box's three axes:
///   compactness = sum_k A_k * (P_k / R_k) / sum_k A_k,
/// A_k the area of the box's face across axis k, R_k the cells of that face
/// on a grid, P_k the cells a point falls into. The grid's cell has the same
/// side on all three faces, chosen so that the three faces together have
/// about points / 8 cells (at most 4096 a side): a surface that fills a face
/// has about 8 points a cell, so sampling gaps do not read as holes. A box's
/// surface (or volume) gives 1, a sphere's about pi/4, a thin diagonal rod
/// little.
float compactness(std::span<const glm::vec3> points, const Obb& box);

/// An oriented box around points: the principal axes of their covariance
/// (Jacobi eigenvectors), extents from the points along them.
Obb fit_obb(std::span<const glm::vec3> points);

/// E of Eq. 3. The paper: "E is the direction vector of the viewpoint",
/// read two ways: the viewing direction, or the direction from the eye to
/// the object's center. The second is the default: a wall along the street
/// faces across the viewing direction (|N . E| near 0) but not across the
/// line of sight to it, and it is what hides the rest of a street; measured
/// in docs/many-objects.md (city block of 10,000: 63 % -> 79 % of the hidden
/// objects culled; box city of 100,000: 81 % -> 86 %).
enum class Facing : std::uint8_t { ViewDirection, EyeToObject };

/// A box inside the solid that a closed surface of points bounds, for an
/// object that is not a box (ObjectBounds::inner; nullopt: none found, the
/// object does not occlude). On a grid of `cells` a side over `box`: the
/// cells holding points are the surface, the empty cells reached from the
/// grid's border through empty cells are outside, the empty cells left are
/// inside; the result is a box of inside cells, grown from the inside cell
/// nearest the center while a whole layer of inside cells can be added.
/// Every path from outside to it crosses a surface cell first. Conservative
/// when the surface is closed and its splats cover every surface cell they
/// are in (points denser than the grid); a scan with holes larger than a
/// cell leaks the outside in, and there is no inside: no inner box, the
/// safe failure. For a box object use the box itself (box_object()).
///
/// `closed_face` (0..5: -x, +x, -y, +y, -z, +z of `box`'s frame; -1: none)
/// closes a surface open on that face (a building without a floor) by the
/// face's plane itself: the outside is not flooded in from that side, and
/// the box found may reach the plane. It is inside the solid that the
/// surface and the plane bound, so it occludes conservatively only for an
/// eye on the inner side of the plane (a ray from there cannot enter through
/// the open face without crossing the plane twice); the caller checks that.
std::optional<Obb> inner_box(std::span<const glm::vec3> points, const Obb& box, int cells = 32,
                             int closed_face = -1);

struct HzmParams {
  unsigned depth_width = 320;           ///< cells across the viewport's larger side
  std::size_t active = 32;              ///< size of the AOS (the paper: 15 and 20)
  float compactness_threshold = 0.55f;  ///< CT (the paper: 0.55 and 0.88)
  Facing facing = Facing::EyeToObject;  ///< E of Eq. 3
  /// Added to the paper: an object the Eq. 5 level keeps is tested again
  /// this many levels finer (up to 2^(k+1) x 2^(k+1) cells; 0 = the paper's
  /// test only; default 2, docs/many-objects.md). A finer level's cells bound fewer pixels, so it
  /// culls at least what the coarser one does, and is as conservative.
  int finer_levels = 2;
};

/// Max-reduction pyramid over a depth image (eye depths, +inf = empty).
class HierarchicalZMap {
 public:
  /// Rebuilds the levels from `base` (width x height, row-major, y up),
  /// each level's rows data-parallel on `pool` (may be null).
  void build(std::span<const float> base, int width, int height, WorkerPool* pool);
  [[nodiscard]] int levels() const { return static_cast<int>(levels_.size()); }
  [[nodiscard]] int width(int level) const { return dims_[static_cast<std::size_t>(level)].x; }
  [[nodiscard]] int height(int level) const { return dims_[static_cast<std::size_t>(level)].y; }
  [[nodiscard]] float at(int level, int x, int y) const {
    const std::size_t l = static_cast<std::size_t>(level);
    return levels_[l][static_cast<std::size_t>(y) * static_cast<std::size_t>(dims_[l].x) +
                      static_cast<std::size_t>(x)];
  }
  /// Eq. 5: the level for a bounding square of `r` level-0 cells a side
  /// (ceil(log2 r), r <= 1 -> 0), clamped to the coarsest level.
  [[nodiscard]] int level_for(int r) const;
  /// The largest value over the level-0 cell range [x0, x1] x [y0, y1]
  /// (inclusive) read at level_for(): at most 2 x 2 cells.
  [[nodiscard]] float max_over(int x0, int y0, int x1, int y1, int* level = nullptr) const;
  /// The largest value over the same range read at `level` (clamped to
  /// [0, levels() - 1]).
  [[nodiscard]] float max_over_at(int level, int x0, int y0, int x1, int y1) const;

 private:
  std::vector<std::vector<float>> levels_;
  std::vector<glm::ivec2> dims_;
};

/// What a frame decided for an object.
enum class ObjectState : std::uint8_t {
  Outside,   ///< frustum culled
  Occluded,  ///< culled by the HZM
  Visible,   ///< potentially visible
  Occluder,  ///< in the AOS and not hidden by the other occluders
};

struct CullStats {
  std::size_t in_frustum = 0;
  std::size_t candidates_in_frustum = 0;  ///< COS members in the frustum
  std::size_t occluders = 0;              ///< |AOS| this frame
  std::size_t occluded = 0;
  std::size_t visible = 0;  ///< potentially visible, occluders included
};

/// Eq. 3 weight of an object as an occluder under `view` (0 when it cannot be
/// one this frame: outside, crossing the near plane, eye inside its AABB).
/// `normal`: the unit normal of its OBB's largest face.
float occluder_weight(const ObjectBounds& object, glm::vec3 normal, const ScreenRect& rect,
                      const ViewSnapshot& view, Facing facing = Facing::EyeToObject);

class HzmCuller {
 public:
  explicit HzmCuller(HzmParams params = {}) : params_(params) {}
  [[nodiscard]] const HzmParams& params() const { return params_; }

  /// Section 6.1: the COS of `objects` (their compactness must be set) and
  /// each candidate's largest-face normal; a copy of the AABBs for the
  /// projection. Call again when objects change or move.
  void preprocess(std::span<const ObjectBounds> objects);
  /// COS: object indices, compactness descending (ties by index).
  [[nodiscard]] std::span<const std::uint32_t> candidates() const { return cos_; }

  /// The four phases of a frame, in this order (or cull() for all four).
  void project(std::span<const ObjectBounds> objects, const ViewSnapshot& view, WorkerPool* pool);
  void select_occluders(std::span<const ObjectBounds> objects, const ViewSnapshot& view,
                        WorkerPool* pool);
  void build_hzm(std::span<const ObjectBounds> objects, const ViewSnapshot& view, WorkerPool* pool);
  void test(std::span<const ObjectBounds> objects, WorkerPool* pool);
  void cull(std::span<const ObjectBounds> objects, const ViewSnapshot& view, WorkerPool* pool);

  [[nodiscard]] std::span<const ScreenRect> rects() const { return rects_; }
  [[nodiscard]] std::span<const ObjectState> states() const { return states_; }
  /// 1 where potentially visible (Visible or Occluder): the visible set the
  /// budget takes (budget_items()).
  [[nodiscard]] std::span<const std::uint8_t> visible() const { return visible_; }
  /// The AOS of the frame, weight descending.
  [[nodiscard]] std::span<const std::uint32_t> active() const { return aos_; }
  [[nodiscard]] const HierarchicalZMap& hzm() const { return hzm_; }
  [[nodiscard]] std::span<const float> depth_image() const { return depth_; }
  [[nodiscard]] glm::ivec2 depth_size() const { return depth_dims_; }
  /// Pixels a depth-image cell spans (s).
  [[nodiscard]] int cell_pixels() const { return cell_; }
  [[nodiscard]] CullStats stats() const;

  /// The relative depth margin of the occlusion test.
  static constexpr float kDepthMargin = 1e-5f;

 private:
  HzmParams params_;
  std::vector<Box> bounds_;  // the objects' AABBs at preprocess()
  std::vector<std::uint32_t> cos_;
  std::vector<ScreenRect> rects_;
  std::vector<ObjectState> states_;
  std::vector<std::uint8_t> visible_;
  // The COS in object order, with what Eq. 3 reads of each (AABB, normal):
  // the frame's weights then stream through 40 bytes a candidate and the
  // rectangles in order instead of a ObjectBounds's cache lines picked in
  // compactness order (48 k of 100 k candidates are in a city block's
  // frustum).
  struct Candidate {
    Box bounds;
    glm::vec3 normal;
    std::uint32_t object;
  };
  std::vector<Candidate> by_index_;
  struct Pick {
    float weight;
    std::uint32_t object;
  };
  std::vector<std::vector<Pick>> picks_;  // per chunk, reused every frame
  std::vector<std::uint32_t> aos_;
  std::vector<float> depth_;
  glm::ivec2 depth_dims_{0, 0};
  int cell_ = 1;
  HierarchicalZMap hzm_;
};

/// The exact reference: every object's box (ObjectBounds::box) ray cast at
/// every pixel center of its rectangle, front-most wins (the first surface
/// at or beyond the near plane and not beyond the far plane; ties to the
/// lower index); visible[i] = 1 when object i owns a pixel. `ids`, when
/// given, receives the id buffer (width x height, y up, ~0u = background).
void reference_visibility(std::span<const ObjectBounds> objects, const ViewSnapshot& view,
                          std::vector<std::uint8_t>& visible, WorkerPool* pool,
                          std::vector<std::uint32_t>* ids = nullptr);

/// Culling accuracy against the reference (the paper's Table 4).
struct CullAccuracy {
  std::size_t culled = 0;               ///< occluded by the HZM
  std::size_t hidden = 0;               ///< in the frustum, not seen by the reference
  std::size_t wrongly = 0;              ///< culled but seen by the reference (must be 0)
  std::size_t subpixel = 0;             ///< of `hidden`: the rectangle holds no pixel center
  [[nodiscard]] double ratio() const {  ///< culled / hidden
    return hidden ? static_cast<double>(culled) / static_cast<double>(hidden) : 1.0;
  }
};
CullAccuracy cull_accuracy(const HzmCuller& culler, std::span<const std::uint8_t> reference);

}  // namespace treecut::culling
