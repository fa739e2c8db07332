// The `budget` strategy: budgeted LOD selection over the objects of a scene
// with hierarchical Z-map occlusion culling, after Peng & Cao, "Integrating
// Occlusion Culling and Parallel LOD for Rendering Complex 3D Environments on
// GPU", I3D 2013 (../shared/papers/occlusion-culling-with-parallel-lod.txt,
// sections 5 and 6), on the CPU cores (docs/many-objects.md, "The budget
// strategy").
//
// A scene-level strategy (SceneStrategy): one instance for all objects. Per
// iteration, each phase data-parallel over objects on a WorkerPool that the
// Feedback Stage thread drives:
//   1. frustum culling (every object's world AABB projected, hzm.hpp);
//   2. with culling on: Eq. 3 occluder selection, the HZM build, the Eq. 5
//      test (HzmCuller);
//   3. the shares of Eq. 1 over the potentially visible objects
//      (allocate_budget; a culled object's A_i is 0, so its share goes to
//      the visible ones), PET zeroing small objects;
//   4. each share a cut of its object's hierarchy (best_cut under the
//      object's view), objects in parallel.
// An object without a share gets an empty list (not drawn). The total of
// the cuts' sizes never exceeds N (`points`).
//
// On a single model (iterate()) it is the one-object case without culling
// or Eq. 1: the best cut of at most N points (at least the root).
#pragma once

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "treecut/culling/hzm.hpp"
#include "treecut/culling/many_objects.hpp"
#include "treecut/strategies/budget.hpp"
#include "treecut/strategy.hpp"

namespace treecut::strategies {

/// Counters of the last scene iteration (read them on the thread that runs
/// the strategy, or after the stage stopped).
struct BudgetCounters {
  std::uint64_t objects = 0;
  std::uint64_t visible = 0;           ///< potentially visible (in the frustum, not occluded)
  std::uint64_t frustum_culled = 0;    ///< outside the view frustum
  std::uint64_t occlusion_culled = 0;  ///< culled by the HZM test
  std::uint64_t below_pet = 0;         ///< visible but 0 < A_i < PET: no share
  std::uint64_t receiving = 0;         ///< objects drawn (a share > 0)
  std::uint64_t occluders = 0;         ///< the active occluder set this iteration
  std::uint64_t shares = 0;            ///< sum of the Eq. 1 shares (<= N)
  std::uint64_t selected = 0;          ///< nodes in the objects' cuts (<= shares <= N)
  // Wall time of each phase (steady clock on the stage thread, pool included).
  std::uint64_t project_ns = 0;  ///< projection + frustum culling
  std::uint64_t select_ns = 0;   ///< occluder selection (Eq. 3)
  std::uint64_t hzm_ns = 0;      ///< depth image + max-reduction
  std::uint64_t test_ns = 0;     ///< the Eq. 5 tests
  std::uint64_t budget_ns = 0;   ///< Eq. 1 shares
  std::uint64_t lod_ns = 0;      ///< best_cut of every share
  // CPU time of the same phases: the stage thread's plus the pool workers'
  // (thread CPU clocks; on a loaded machine the wall times above also count
  // waiting for a core, these do not).
  std::uint64_t project_cpu_ns = 0;
  std::uint64_t select_cpu_ns = 0;
  std::uint64_t hzm_cpu_ns = 0;
  std::uint64_t test_cpu_ns = 0;
  std::uint64_t budget_cpu_ns = 0;
  std::uint64_t lod_cpu_ns = 0;
};

class BudgetStrategy final : public Strategy, public SceneStrategy {
 public:
  enum Param : std::size_t {
    kPoints,       ///< N, the global point budget
    kAlpha,        ///< exponent of Eq. 1
    kPet,          ///< pixel error threshold, square pixels
    kCulling,      ///< 1: HZM occlusion culling, 0: frustum culling only
    kOccluders,    ///< size of the active occluder set
    kCompactness,  ///< CT: compactness threshold of the candidate occluders
    kThreads,      ///< worker pool size (the stage thread included)
  };

  BudgetStrategy();
  ~BudgetStrategy() override;

  [[nodiscard]] std::string_view name() const override { return "budget"; }
  [[nodiscard]] Mode mode() const override { return Mode::Rebuild; }
  void iterate(const IterationInput& input, IterationOutput& output) override;
  void reset(const Hierarchy& hierarchy) override;

  void reset_scene(const StageScene& scene) override;
  void iterate_scene(const SceneIterationInput& input, SceneIterationOutput& output) override;

  [[nodiscard]] const BudgetCounters& last() const { return last_; }
  /// The objects as the culler sees them (world boxes, compactness), from reset_scene().
  [[nodiscard]] std::span<const culling::ObjectBounds> objects() const { return objects_; }
  /// Per object of the last scene iteration: 1 when potentially visible.
  [[nodiscard]] std::span<const std::uint8_t> visible() const { return visible_; }
  /// Per object of the last scene iteration: its Eq. 1 share.
  [[nodiscard]] std::span<const std::uint32_t> shares() const { return shares_; }

 private:
  /// Publishes C as the iteration's named counters (budget_*; treecut/counters.hpp).
  static void publish(const BudgetCounters& c, Counters& out);

  // Per distinct model: its box, compactness and inner box in model space.
  struct ModelShape {
    const Hierarchy* hierarchy = nullptr;
    culling::Obb box;
    std::optional<culling::Obb> inner;
    float compactness = 0.0f;
    glm::vec3 splat_lo{0.0f}, splat_hi{0.0f};  // model-space box of every splat
    int open_face = -1;  // 2 * axis + (1: +side), the face closed to find `inner`; -1: none
  };
  void ensure_pool();
  void ensure_culler();
  /// The shape of model H (PAGED: drawn from its pages); POINTS scratch.
  static ModelShape model_shape(const Hierarchy& h, bool paged, std::vector<glm::vec3>& points);
  /// The POINTS a model drawn from its pages is fitted to (its resident
  /// leaves) and SHAPE's splat box.
  static void paged_points(const Hierarchy& h, std::vector<glm::vec3>& points, ModelShape& shape);

  // The phases of iterate_scene() (budget_strategy.cpp).
  struct PhaseClock;
  /// The open faces' eye-inside test: true when an object's inner box came or went.
  bool update_open_faces(const ViewSnapshot& view);
  /// Projection and frustum culling, with culling on Eq. 3, the HZM and Eq. 5.
  void cull(const ViewSnapshot& view, WorkerPool* pool, PhaseClock& clock, BudgetCounters& c);
  /// The shares of Eq. 1 (shares_) over the potentially visible objects.
  void share_budget(WorkerPool* pool, BudgetCounters& c);
  /// Each share's best cut, written to OUTPUT as the scene's lists; their total size.
  std::size_t select_cuts(const ViewSnapshot& view, WorkerPool& pool, SceneIterationOutput& output);

  std::vector<ModelShape> shapes_;
  std::vector<culling::ObjectBounds> objects_;
  std::vector<const Hierarchy*> hierarchies_;
  std::vector<std::uint32_t> open_;        // objects whose model's inner box needs an open face
  std::vector<glm::dvec4> open_planes_;    // per open_ entry: eye inside when dot(xyz, eye) + w < 0
  std::vector<std::uint8_t> open_inside_;  // per open_ entry: its object's has_inner
  std::vector<glm::mat4> worlds_;
  std::vector<std::uint32_t> points_;  // P_i apart: Eq. 1 reads 4 bytes an object, not 156
  std::unique_ptr<WorkerPool> pool_;
  std::unique_ptr<culling::HzmCuller> culler_;
  culling::HzmParams culler_params_;
  std::vector<std::uint8_t> visible_;
  std::vector<many::BudgetItem> items_;
  std::vector<std::uint32_t> shares_;
  std::vector<std::vector<NodeId>> cuts_;
  std::vector<std::vector<NodeId>> wanted_;  // per object: hidden nodes best_cut would refine
  BudgetCounters last_;
};

}  // namespace treecut::strategies
