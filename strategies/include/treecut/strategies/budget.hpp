// Budgeted LOD selection over many objects: Peng & Cao, "Integrating
// Occlusion Culling and Parallel LOD for Rendering Complex 3D Environments on
// GPU", I3D 2013 (../shared/papers/occlusion-culling-with-parallel-lod.txt),
// section 5, Eq. 1 and the pixel error threshold (PET).
//
// Eq. 1, the share of object i of a global budget of N points:
//
//     vc_i = N * w_i^(1/alpha) / sum_j w_j^(1/alpha),
//     w_i  = beta * (A_i / D_i) * P_i^beta,   beta = alpha - 1,
//
// A_i the area of the screen rectangle of the projected AABB (square
// pixels), D_i its nearest eye depth, P_i the points the object has. (Our
// text of the paper lost the equation's layout; this is its reading. The
// factor beta multiplies every w_i alike and cancels in the ratio: only the
// exponents matter.) The paper: "If A_i is below a given PET, vc_i is set to
// zero", so PET compares with the area in square pixels.
//
// What the paper leaves open and this adds:
//   - A share is a count of points, so it is capped at P_i (an object cannot
//     draw more points than it has), and what the capped objects leave is
//     shared among the others by the same formula (water filling: the
//     shares are min(P_i, lambda * w_i^(1/alpha)) with the one lambda that
//     spends min(N, sum P_i); capping raises lambda, so the objects capped
//     first stay capped).
//   - The shares are integers: floors of the real shares, and the points the
//     floors leave go one each to the largest fractional parts (ties to the
//     smaller index). So the total is exactly min(N, sum of P_i over the
//     objects that get a share) and never above N.
//   - An object with A_i = 0 (frustum culled or occluded: the caller passes
//     the visible set that way) or P_i = 0 gets nothing; D_i is clamped to
//     a small positive value (the near plane in practice).
//
// Each share becomes a cut of that object's hierarchy: best_cut(), the best
// cut of at most n nodes by the optimization strategy's priority
// (OptimizationStrategy::priority, the same function, not a copy).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "treecut/culling/many_objects.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::strategies::many {

struct BudgetParams {
  std::uint64_t total = 1'000'000;  ///< N: points for the whole scene
  double alpha = 3.0;               ///< the exponent of Eq. 1 (> 1; the paper uses 3)
  double pet = 1.0;                 ///< PET, square pixels: smaller A_i get nothing
};

/// One object's terms of Eq. 1.
struct BudgetItem {
  float area = 0.0f;         ///< A_i, square pixels (0: not visible)
  float depth = 0.0f;        ///< D_i, eye units
  std::uint32_t points = 0;  ///< P_i
};

/// w_i^(1/alpha) of Eq. 1 (without the factor beta, which cancels), 0 when
/// the item gets nothing (area below PET, no area or no points).
double eq1_term(const BudgetItem& item, const BudgetParams& params);

struct BudgetStats {
  std::uint64_t total = 0;    ///< sum of the shares (<= N)
  std::size_t receiving = 0;  ///< objects with a share > 0
  std::size_t below_pet = 0;  ///< objects with 0 < A_i < PET
  std::size_t capped = 0;     ///< objects whose share is all their points
  std::size_t rounds = 0;     ///< water-filling rounds
  double lambda = 0.0;        ///< the final multiplier of w^(1/alpha)
};

/// The per-object shares (Eq. 1 with the cap and the integer rounding above)
/// into `shares` (resized to items.size()). The pass over all objects (the
/// terms, PET) is data-parallel on `pool` (nullptr: the calling thread
/// only) and keeps the objects with a term > 0 in index order; the water
/// filling and the rounding run on that list (the visible objects, a few
/// thousand of 100,000 in a street view). The result does not depend on the
/// thread count.
BudgetStats allocate_budget(std::span<const BudgetItem> items, const BudgetParams& params,
                            std::vector<std::uint32_t>& shares, WorkerPool* pool = nullptr);

/// The real-valued Eq. 1 share of every item without cap or rounding,
/// N * t_i / sum t_j: the formula itself, for tests and documentation.
std::vector<double> eq1_shares(std::span<const BudgetItem> items, const BudgetParams& params);

/// Items from the screen rectangles of `objects` under `view`, with the area
/// zeroed where `visible` is 0 (culled objects give their share to the
/// others); `visible` empty = all.
void budget_items(std::span<const culling::ObjectBounds> objects,
                  std::span<const culling::ScreenRect> rects, std::span<const std::uint8_t> visible,
                  std::vector<BudgetItem>& items, WorkerPool* pool = nullptr);
/// The same with P_i given apart (points[i] = objects[i].points): what a
/// caller that keeps them in an array passes, 4 bytes an object to read.
void budget_items(std::span<const std::uint32_t> points, std::span<const culling::ScreenRect> rects,
                  std::span<const std::uint8_t> visible, std::vector<BudgetItem>& items,
                  WorkerPool* pool = nullptr);

struct CutParams {
  float curvature_weight = 0.5f;  ///< as the optimization strategy's parameter
  float min_size = 0.5f;          ///< pixels: nodes projecting smaller are not refined
};

/// The best cut of at most `n` nodes of `h` by the optimization strategy's
/// priority under `view` (an object_view()): from the root, the cut node of
/// highest priority is refined while its children fit (greedy, O(n log n)).
/// A node projecting smaller than min_size, outside the frustum (priority 0)
/// or a leaf stays; a node whose children do not fit stays and the next is
/// tried. Priorities are monotone (a parent's >= a child's), so the refined
/// nodes are the highest-priority ones: no coarsenable parent of the result
/// ranks below a refinable cut node with at most as many children (the
/// optimization strategy's converged state). n = 0: the empty list (the
/// object is not drawn); otherwise at least the root.
std::vector<NodeId> best_cut(const Hierarchy& h, const ViewSnapshot& view, std::size_t n,
                             const CutParams& params = {});
/// The same cut into `cut` (cleared first; its storage is reused, as is a
/// per-thread heap: no allocation per object per iteration once the lists
/// have grown). WANTED (if not null) gets the hidden nodes of a paged
/// model (Hierarchy::is_hidden) that the cut would have refined by the same
/// rule had their children been resident.
void best_cut(const Hierarchy& h, const ViewSnapshot& view, std::size_t n, std::vector<NodeId>& cut,
              const CutParams& params = {}, std::vector<NodeId>* wanted = nullptr);

}  // namespace treecut::strategies::many
