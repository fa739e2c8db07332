// HOQ-coherent HLOD refinement: J. P. Charalambos, J. Bittner, M. Wimmer,
// E. Romero, "Optimized HLOD Refinement Driven by Hardware Occlusion
// Queries", ISVC 2007 (../shared/papers/hoq-driven-hlod-refinement.txt).
//
// Two parts:
// - Pure functions of explicit inputs (namespace hoq): the sigmoid bias
//   B_{s,t}(mu), VMSSE = B * SSE (equation 1), the screen-space error of an
//   HLOD block, the relative visibility mu of a query answer and
//   PredictRefinement of the paper's figure 3. The in-frame traversals (Bool,
//   SW(B), Simp(B), Coh(B) on the occlusion device) call the same functions.
// - HoqStrategy (`hoq`), the Feedback Stage form: the same prediction on the
//   stage thread over a cut of HLOD blocks (hlod_blocks.hpp). Its queries go
//   through the View's executor and their answers reach the strategy frames
//   later; the render thread never waits. docs/occlusion.md ("## HOQ")
//   describes how that latency maps onto the paper's delay and RARN, with
//   measured figures.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "treecut/strategies/hlod_blocks.hpp"
#include "treecut/strategy.hpp"

namespace treecut::strategies {

namespace hoq {

/// The sigmoid bias B_{s,t}(mu) of section 3.2 (figure 1-a): the paper names
/// its properties, not its formula, so this is the smooth quadratic sigmoid
/// with turn-over t,
///     S_t(mu) = mu^2 / t                      for mu <= t  (aggressive: S < mu)
///     S_t(mu) = 1 - (1 - mu)^2 / (1 - t)      for mu >  t  (conservative: S > mu)
/// (continuous with a continuous slope at t, S_t(0) = 0, S_t(1) = 1), and the
/// smoothness s interpolating linearly between mu and it:
///     B_{s,t}(mu) = (1 - s) mu + s S_t(mu).
/// Hence s = 0 gives mu, mu = 1 gives 1 for every s and t, B is
/// non-decreasing in mu, and a t closer to 0 modulates less (more
/// conservative), as the paper asks. mu, s and t are clamped to [0, 1].
[[nodiscard]] float sigmoid_bias(float mu, float s, float t);

/// Equation 1: VMSSE = B_{s,t}(mu) * SSE.
[[nodiscard]] inline float vmsse(float bias, float sse) {
  return bias * sse;
}

/// Distance from `eye` to the nearest point of `box` (0 inside it).
[[nodiscard]] float distance_to_box(glm::vec3 eye, const Box& box);

/// The screen-space error of an HLOD block in pixels: `error_radius` (the
/// largest splat radius of the block's representation, 0 for a leaf block,
/// which is full detail) projected at the nearest distance of the block's
/// box, as ViewSnapshot::projected_radius_px projects a radius. Conservative:
/// every splat the block draws lies inside its box, so none is nearer than
/// that distance and none is larger than that radius: no splat of the
/// representation projects larger than this. Orthographic: radius times the
/// pixel scale.
[[nodiscard]] float block_sse(const ViewSnapshot& view, const Box& box, float error_radius);

/// The camera of one frame, enough to redo a query's geometry.
struct QueryCamera {
  glm::mat4 view{1.0f};
  glm::mat4 projection{1.0f};
  glm::ivec2 viewport{1, 1};
};

/// The pixels the View's executor rasterizes for the query of a sphere
/// (treecut/splat/query_executor.hpp): its window rectangle (exact tangent
/// planes, 1/8 pixel wider on each side) clipped to the viewport, as the
/// point sprite of the longer side centred on it, clipped to the viewport
/// again. 0 when the rectangle misses the view. Negative (no analytic count)
/// when the sphere is not entirely in front of the eye's plane or the
/// projection is not a perspective frustum: the executor then draws a quad
/// or answers on the host, and relative_visibility() treats any sample as
/// mu = 1.
[[nodiscard]] double proxy_pixels(const QueryCamera& camera, glm::vec3 center, float radius);

/// mu = unoccluded pixels / projected pixels in [0, 1]; 0 for no sample; 1
/// for any sample when `projected_pixels` <= 0 (no analytic count: never
/// aggressive).
[[nodiscard]] float relative_visibility(std::uint32_t samples_passed, double projected_pixels);

enum class Prediction : std::uint8_t { Refine, Stop, Delay };

/// What PredictRefinement reads of a node: the state cached in the last frame.
struct NodeState {
  bool visited_last_frame = false;  ///< node.lastVisited = frameID - 1
  bool visible = false;             ///< node.visible (last frame's answer)
  bool stop_refinement = false;     ///< node.stopRefinement (a termination node last frame)
  float bias = 1.0f;                ///< node.bias: B(mu) of last frame's answer
};

/// What it reads of each child: its stop flag and cached bias, and its SSE
/// in this frame.
struct ChildState {
  bool stop_refinement = false;
  float bias = 1.0f;
  float sse = 0.0f;
};

/// AvgBias: the mean cached bias of the children (1 for none).
[[nodiscard]] float average_bias(std::span<const ChildState> children);

/// PredictRefinement(node), the paper's figure 3, line by line:
///     if not visited last frame or invisible:                 Delay
///     if not stopped last frame (refined):
///        candidate to shift up = every child stopped and
///                                child.bias * SSE(child) <= tau
///        if candidate and AvgBias(children) * SSE(node) <= tau: Delay
///     else if node.bias * SSE(node) <= tau:                   Stop
///     Refine
/// `sse` is the node's SSE in this frame; `children` is read only for a
/// refined node.
[[nodiscard]] Prediction predict_refinement(const NodeState& node, float sse,
                                            std::span<const ChildState> children, float tau);

}  // namespace hoq

/// Counters of one iteration of HoqStrategy (and their sums since reset()).
struct HoqCounters {
  std::uint64_t blocks = 0;  ///< blocks in the block cut
  std::uint64_t drawn = 0;   ///< DN: cut blocks not known invisible
  std::uint64_t culled = 0;  ///< cut blocks known invisible (frustum, or 0 samples)
  /// D: blocks whose decision waits for an answer (not known invisible); of
  /// them `delayed_shift_up` are refined blocks, candidates to shift up (their
  /// children drawn meanwhile), the rest termination blocks waiting for a
  /// first answer (drawn at their level meanwhile).
  std::uint64_t delayed = 0;
  std::uint64_t delayed_shift_up = 0;
  /// RARN in the stage form: a block the prediction drew (Stop) whose newer
  /// answer showed VMSSE > tau: it was drawn too coarse from the frame that
  /// answer was issued in until its refinement is drawn (rarn_frames sums
  /// those frames).
  std::uint64_t rarn = 0;
  std::uint64_t rarn_frames = 0;
  /// A block kept at its level while it waited (delayed) or while it was
  /// hidden (culled) whose answer said visible and refine: drawn too coarse
  /// since it entered or since that answer was issued (late_frames sums the
  /// frames).
  std::uint64_t late_refined = 0;
  std::uint64_t late_frames = 0;
  std::uint64_t refined = 0;    ///< blocks refined now that were not refined in the last iteration
  std::uint64_t coarsened = 0;  ///< blocks that replaced their subtree's blocks
  std::uint64_t queries = 0;    ///< query requests posted
  std::uint64_t answers = 0;    ///< answers taken in (of this strategy's blocks)
  /// Latency of the answers taken in: sum of (this iteration's frame -
  /// frame_issued) and of (frame_read - frame_issued).
  std::uint64_t answer_age_frames = 0;
  std::uint64_t answer_gpu_frames = 0;

  void add(const HoqCounters& o);
};

/// The `hoq` strategy (Rebuild): a cut of HLOD blocks refined with the
/// paper's prediction, one occlusion query per block it needs mu of.
class HoqStrategy final : public Strategy {
 public:
  enum Param : std::size_t {
    kTheta,      ///< tau: pixels of error
    kS,          ///< smoothness of the bias
    kT,          ///< turn-over of the bias
    kBlockSize,  ///< leaves per leaf block (HlodBlocks::build)
    /// 1: a block new in the traversal (the paper's Delay for "not visited
    /// last frame") is refined by SSE alone, as if visible, while its first
    /// answer is on its way; 0: it keeps its level until then.
    kAssumeVisible,
    /// 1: VMSSE with the bias; 0: Bool (the paper's scenario and image
    /// reference): SSE alone, the answers used only as visible or not.
    kBias,
  };

  HoqStrategy();
  [[nodiscard]] std::string_view name() const override { return "hoq"; }
  [[nodiscard]] Mode mode() const override { return Mode::Rebuild; }
  [[nodiscard]] bool asks_queries() const override { return true; }
  void reset(const Hierarchy& hierarchy) override;
  void iterate(const IterationInput& input, IterationOutput& output) override;

  /// The last iteration's counters and their sums since reset(): stage
  /// thread (or the owner when no stage runs the strategy, as `render --sync`).
  [[nodiscard]] const HoqCounters& last() const { return last_; }
  [[nodiscard]] const HoqCounters& totals() const { return totals_; }
  [[nodiscard]] std::uint64_t iterations() const { return iteration_; }
  [[nodiscard]] const HlodBlocks& blocks() const { return blocks_; }
  /// The block cut of the last iteration.
  [[nodiscard]] std::span<const BlockId> block_cut() const { return cut_; }

 private:
  // Front: new in the traversal, drawn at its level; Hidden: invisible last
  // frame, culled; ShiftUp: refined, a candidate to move the front up.
  enum class Delay : std::uint8_t { None, Front, Hidden, ShiftUp };
  struct BlockState {
    std::uint64_t visited = 0;       // iteration it was last traversed in (0: never)
    std::uint64_t answer_frame = 0;  // frame_issued of the newest answer taken in
    std::uint64_t delay_after = 0;   // a delay is resolved by an answer issued after this frame
    std::uint64_t delay_frame = 0;   // the frame the delay began in
    float bias = 1.0f;               // B(mu) of the newest answer
    float stop_bias = 1.0f;          // the bias its last Stop was predicted with
    bool visible = true;             // newest answer (terminal) or pulled up (refined)
    bool stop = false;               // a termination block (in the cut) at its last visit
    bool outside = false;            // culled by the frustum at its last visit
    bool culled = false;             // a termination block known invisible at its last visit
    Delay delay = Delay::None;
  };

  void build_blocks(const Hierarchy& h);
  void take_answers(const IterationInput& input);
  void visit(BlockId b, const IterationInput& input, IterationOutput& output);
  void terminal(BlockId b, bool known_invisible);
  void query(BlockId b, const IterationInput& input, IterationOutput& output);
  void children_states(BlockId b, const ViewSnapshot& view);
  [[nodiscard]] const hoq::QueryCamera* camera_of(std::uint64_t frame) const;

  HlodBlocks blocks_;
  std::vector<float> error_radius_;  // per block: the largest splat radius of its representation
  std::vector<BlockState> state_;
  std::vector<BlockId> cut_, previous_cut_;
  std::vector<BlockId> stack_;
  std::vector<hoq::ChildState> children_;
  const Hierarchy* hierarchy_ = nullptr;
  std::uint32_t built_block_size_ = 0;
  std::uint64_t iteration_ = 0;
  std::uint64_t frame_ = 0;
  std::uint64_t last_version_ = ~std::uint64_t{0};
  std::uint64_t last_params_ = ~std::uint64_t{0};
  std::uint32_t settled_ = 0;  // iterations in a row with the same view and block cut
  // The cameras of the last frames an iteration saw, by frame: a query's
  // projected pixels are counted with the camera of the frame it was issued in.
  struct FrameCamera {
    std::uint64_t frame = 0;
    hoq::QueryCamera camera;
  };
  static constexpr std::size_t kCameras = 16;
  FrameCamera cameras_[kCameras]{};
  std::size_t camera_count_ = 0;
  HoqCounters last_, totals_;
};

}  // namespace treecut::strategies
