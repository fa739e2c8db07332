// HOQ-coherent HLOD refinement: J. P. Charalambos, J. Bittner, M. Wimmer,
// E. Romero, "Optimized HLOD Refinement Driven by Hardware Occlusion
// Queries", ISVC 2007 (../shared/papers/hoq-driven-hlod-refinement.txt).
//
// The paper's pure functions (the sigmoid bias, VMSSE, the screen-space error
// of a block, mu, PredictRefinement) are in the culling layer,
// treecut/culling/hoq_refinement.hpp, shared with the in-frame traversals
// (Bool, SW(B), Simp(B), Coh(B) on the occlusion device). This file is
// HoqStrategy (`hoq`), the Feedback Stage form: the same prediction on the
// stage thread over a cut of HLOD blocks, made as the traversal reaches them
// among the resident nodes (resident_blocks.hpp: a model drawn from its
// pages works as one held whole). Its queries go
// through the View's executor and their answers reach the strategy frames
// later; the render thread never waits. docs/occlusion.md ("## HOQ")
// describes how that latency maps onto the paper's delay and RARN, with
// measured figures.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "treecut/culling/hlod_blocks.hpp"
#include "treecut/culling/hoq_refinement.hpp"
#include "treecut/culling/resident_blocks.hpp"
#include "treecut/strategy.hpp"

namespace treecut::strategies {

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
  /// The block cut of the last iteration, each block named by its node (a
  /// block of fan-out 4 is one node: HlodBlocks::block_of_root gives its id
  /// among HlodBlocks::build(h, block_size, 4)'s).
  [[nodiscard]] std::span<const NodeId> block_cut() const { return cut_; }
  /// The blocks made so far (those the traversal reached among the resident nodes).
  [[nodiscard]] std::size_t blocks_made() const { return blocks_.size(); }

 private:
  /// Publishes C as the iteration's named counters (hoq_*; treecut/counters.hpp).
  static void publish(const HoqCounters& c, Counters& out);

  // Front: new in the traversal, drawn at its level; Hidden: invisible last
  // frame, culled; ShiftUp: refined, a candidate to move the front up.
  enum class Delay : std::uint8_t { None, Front, Hidden, ShiftUp };
  struct BlockState {
    NodeId node = kNoNode;           // the block's node (an answer's check)
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
    bool hidden = false;             // a leaf block only until its children's pages arrive
    Delay delay = Delay::None;
  };

  // What visit() found for a block: what it was at its last visit, its SSE
  // now and tau; read by the steps that decide it (inlined into visit()).
  struct Visit {
    NodeId block;
    std::uint32_t slot;  // its state_ and ResidentBlocks slot
    bool was_visited;
    bool was_refined;
    bool was_terminal;
    float sse;
    float tau;
  };

  void build_blocks(const Hierarchy& h);
  void follow_residency(const IterationInput& input);
  void append_representations(std::vector<NodeId>& out, bool memory_short) const;
  // The state of the block in SLOT, made on first use.
  BlockState& state(std::uint32_t slot);
  void take_answers(const IterationInput& input);
  // Returns whether the block is visible (pulled up into its parent).
  bool visit(NodeId b, const IterationInput& input, IterationOutput& output);
  void refine(const Visit& v, const IterationInput& input, IterationOutput& output);
  void decide_delayed(const Visit& v, const IterationInput& input, IterationOutput& output);
  void follow_prediction(const Visit& v, const IterationInput& input, IterationOutput& output);
  void refine_predicted(const Visit& v, const IterationInput& input, IterationOutput& output);
  void delay_decision(const Visit& v, const IterationInput& input, IterationOutput& output);
  void terminal(std::uint32_t slot, bool known_invisible, IterationOutput& output);
  void query(std::uint32_t slot, const IterationInput& input, IterationOutput& output);
  void children_states(NodeId b, const IterationInput& input);
  [[nodiscard]] const ViewSnapshot* camera_of(std::uint64_t frame) const;

  culling::ResidentBlocks blocks_;
  // By the block's slot (ResidentBlocks::Block::slot): the blocks the
  // traversal has reached (reset when a block is dropped with the pages
  // below a concealed node).
  std::deque<BlockState> state_;
  std::vector<NodeId> cut_, previous_cut_;
  std::vector<std::uint32_t> cut_slots_;  // cut_'s blocks' slots
  std::vector<std::uint32_t> dropped_;
  std::vector<culling::hoq::ChildState> children_;
  const Hierarchy* hierarchy_ = nullptr;
  std::uint32_t hierarchy_nodes_ = 0;
  std::uint64_t iteration_ = 0;
  std::uint64_t frame_ = 0;
  std::uint64_t last_version_ = ~std::uint64_t{0};
  std::uint64_t last_params_ = ~std::uint64_t{0};
  std::uint32_t settled_ = 0;  // iterations in a row with the same view and block cut
  // The cameras of the last frames an iteration saw, by frame: a query's
  // projected pixels are counted with the camera of the frame it was issued in.
  struct FrameCamera {
    std::uint64_t frame = 0;
    ViewSnapshot camera;  // view, projection, viewport and derived; no visibility
  };
  static constexpr std::size_t kCameras = 16;
  FrameCamera cameras_[kCameras]{};
  std::size_t camera_count_ = 0;
  HoqCounters last_, totals_;
};

}  // namespace treecut::strategies
