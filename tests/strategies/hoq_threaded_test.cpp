// The query channel of the Feedback Stage on a real stage thread (the TSan
// configuration's view of it): `hoq` (Charalambos et al. 2007, in the
// design card's stage form) asks for queries with each list, the render loop
// stand-in answers them frames later through post_visibility while the next
// iteration may be running, and a model switch in the middle drops the
// answers about the old model. hoq_test.cpp drives the same channel with
// Launch::Manual; here the two threads really overlap.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "strategy_fixtures.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/strategies/hoq.hpp"

namespace treecut {
namespace {

// What the executor would read for q: 0 samples for blocks whose root lies
// in the western half of the model (hidden), the proxy's pixels otherwise.
VisibilityResult answer(const Hierarchy& h, const ViewSnapshot& view, const QueryRequest& q,
                        std::uint64_t issued) {
  namespace hoq = culling::hoq;
  const treecut::ViewSnapshot& cam = view;
  const glm::vec4 s = h.arrays().center_radius[q.node];
  const double pixels = hoq::proxy_pixels(cam, glm::vec3(s), s.w);
  const float mid = 0.5f * (h.bounds_min().x + h.bounds_max().x);
  VisibilityResult r;
  r.object = q.object;
  r.node = q.node;
  r.tag = q.tag;
  r.samples_passed =
      s.x < mid ? 0u : std::uint32_t(pixels < 0.0 ? 640.0 * 360.0 : std::max(1.0, pixels));
  r.frame_issued = issued;
  r.frame_read = issued + 1;
  r.kind = q.kind;
  return r;
}

TEST(HoqThreaded, AnswersCrossToTheStageThreadAndEveryListIsValid) {
  const auto city = test::small_hierarchy(tools::ModelKind::City, 20000);
  const auto other = test::small_hierarchy(tools::ModelKind::City, 12000);
  auto owned = std::make_unique<strategies::HoqStrategy>();
  owned->set_param("block_size", 200);
  owned->set_param("theta", 2.0);
  const strategies::HoqStrategy* hoq_strategy = owned.get();
  FeedbackStage stage(Model{city, TreeCut::root_cut(*city)}, std::move(owned));

  std::mt19937 rng(11);
  std::shared_ptr<const Hierarchy> current = city;
  std::vector<VisibilityResult> next;  // read in the next frame, issued in this one
  std::uint64_t generation = 0, lists = 0, posted = 0;
  // Frames run at the render loop's pace, iterations at the stage's: the
  // loop ends after a number of lists, not of frames (a hang is the CTest
  // timeout's to catch).
  const std::uint64_t wanted = 120;
  bool switched = false;
  for (int frame = 0; lists < wanted; ++frame) {
    if (!switched && lists == wanted / 2) {
      switched = true;
      // Answers about the old model may still be in flight: the stage drops them.
      current = other;
      stage.set_model(Model{other, TreeCut::root_cut(*other)});
    }
    ViewSnapshot view = test::street_view(*current, float(frame % 3000) / 2000.0f);
    view.version = std::uint64_t(frame) + 1;
    stage.set_view(view);
    const FrameLists f = stage.poll();
    if (!next.empty()) {
      stage.post_visibility(next);
      posted += next.size();
      next.clear();
    }
    if (f.current.generation != generation) {
      generation = f.current.generation;
      ASSERT_EQ(TreeCut::validate(*f.current.hierarchy, f.current.nodes), "")
          << "generation " << generation;
      ++lists;
      // A list's queries are about its own hierarchy.
      for (const QueryRequest& q : f.current.queries) {
        ASSERT_LT(q.node, f.current.hierarchy->node_count());
        next.push_back(answer(*f.current.hierarchy, view, q, stage.frame()));
      }
    }
    // The frame's own work, so that iterations overlap frames at varied phases.
    if (rng() % 4 == 0) std::this_thread::yield();
  }
  // The stage's last writes to the strategy happen before these reads.
  while (stage.processing()) std::this_thread::yield();

  EXPECT_EQ(stage.counters().errors, 0u) << stage.counters().last_error;
  EXPECT_GT(posted, 0u);
  const strategies::HoqCounters& t = hoq_strategy->totals();
  EXPECT_GT(t.answers, 0u);
  EXPECT_LE(t.answers, t.queries);
  EXPECT_GT(t.culled, 0u);  // the hidden half
  EXPECT_GT(t.drawn, 0u);
  // Issued in frame X, posted in X + 1 after that frame's request, taken by
  // an iteration requested in X + 2 or later: the threads add frames, never
  // take any away.
  EXPECT_GE(t.answer_age_frames, 2 * t.answers);
}

}  // namespace
}  // namespace treecut
