// CHC traversal (treecut/culling/chc.hpp) on the CPU device of
// sheets_device.hpp, against its brute-force reference.
#include "sheets_device.hpp"

namespace {

TEST_F(Chc, TheSceneHasOcclusionAndAnOffScreenPart) {
  FakeDevice d(blocks_, 0);
  const auto in = leaves_in_frustum(d);
  const auto seen = truth(d);
  EXPECT_GE(seen.size(), 3u);
  EXPECT_GE(in.size(), seen.size() + 3) << "some leaf blocks must be hidden";
  EXPECT_LT(in.size(), blocks_.leaf_block_count()) << "some leaf blocks must be off screen";
}

TEST_F(Chc, VfcDrawsEveryLeafBlockInTheFrustumWithoutQueries) {
  FakeDevice d(blocks_, 2);
  ChcTraversal t(blocks_, {OcclusionMode::Vfc});
  const ChcFrameStats s = t.frame_render_thread(d, view_from({-3, 0, 0}));
  const auto in = leaves_in_frustum(d);
  const auto drawn = as_set(t.drawn());
  // Every leaf block on screen; none of the off-screen cluster (a box that
  // meets the frustum but covers no pixel centre may be drawn too).
  for (const BlockId b : in) EXPECT_TRUE(drawn.count(b)) << b;
  for (const BlockId b : drawn) EXPECT_LT(blocks_.box(b).lo.y, 30.0f) << b;
  EXPECT_EQ(s.queries, 0u);
  EXPECT_EQ(s.blocks_drawn, drawn.size());
  EXPECT_GT(s.frustum_culled, 0u);
}

TEST_F(Chc, StopAndWaitDrawsExactlyTheVisibleLeafBlocksAndWaitsForEveryQuery) {
  FakeDevice d(blocks_, 3);
  ChcTraversal t(blocks_, {OcclusionMode::StopAndWait});
  d.watch(&t);
  const ChcFrameStats s = t.frame_render_thread(d, view_from({-3, 0, 0}));
  EXPECT_EQ(as_set(t.drawn()), truth(d));
  EXPECT_EQ(as_set(t.visible_leaves()), truth(d));
  EXPECT_EQ(s.leaves_visible, truth(d).size());
  // Every query blocked (latency 3), even with work in the traversal queue.
  EXPECT_EQ(s.blocking_reads, s.queries);
  EXPECT_GT(d.blocked_with_work, 0u) << "the counter of the CHC test below is live";
}

TEST_F(Chc, IdealDrawsTheStopAndWaitSetWithNoQuery) {
  FakeDevice d(blocks_, 3);
  ChcTraversal sw(blocks_, {OcclusionMode::StopAndWait});
  sw.frame_render_thread(d, view_from({-3, 0.3f, 0}));
  const auto set = sw.drawn();
  ChcTraversal ideal(blocks_, {OcclusionMode::Ideal});
  ideal.set_ideal_leaves(set);
  const ChcFrameStats s = ideal.frame_render_thread(d, view_from({-3, 0.3f, 0}));
  EXPECT_EQ(as_set(ideal.drawn()), as_set(set));
  EXPECT_EQ(ideal.drawn(), set) << "the same front-to-back order";
  EXPECT_EQ(s.queries, 0u);
  EXPECT_EQ(d.frame_stats().queries, 0u);
}

// The bench's diagnostic row: Ideal's draws, in Ideal's order, with one box
// query before each (answers ignored).
TEST_F(Chc, IdealWithProbeQueriesDrawsTheSameSetAndQueriesEachDrawnBlock) {
  FakeDevice d(blocks_, 3);
  ChcTraversal sw(blocks_, {OcclusionMode::StopAndWait});
  sw.frame_render_thread(d, view_from({-3, 0.3f, 0}));
  const auto set = sw.drawn();
  ASSERT_FALSE(set.empty());
  ChcOptions o{OcclusionMode::Ideal};
  o.ideal_probe_queries = true;
  ChcTraversal probe(blocks_, o);
  probe.set_ideal_leaves(set);
  const ChcFrameStats s = probe.frame_render_thread(d, view_from({-3, 0.3f, 0}));
  EXPECT_EQ(probe.drawn(), set);
  EXPECT_EQ(s.queries, set.size());
  EXPECT_EQ(d.frame_stats().queries, set.size());
}

TEST_F(Chc, ChcIsConservativeEveryFrameAndExactOnceTheViewStops) {
  FakeDevice d(blocks_, 4);
  ChcTraversal t(blocks_, {OcclusionMode::Chc});
  for (int f = 0; f < 30; ++f) {
    const float y = f < 20 ? -1.5f + 0.15f * f : 1.5f;  // moves, then stands
    d.set_eye({-3, y, 0.2f});
    t.frame_render_thread(d, view_from({-3, y, 0.2f}));
    const auto seen = truth(d);
    const auto drawn = as_set(t.drawn());
    for (const BlockId b : seen) EXPECT_TRUE(drawn.count(b)) << "frame " << f << " culled " << b;
    if (f >= 22) {
      EXPECT_EQ(drawn, seen) << "frame " << f;
      EXPECT_EQ(as_set(t.visible_leaves()), seen) << "frame " << f;
    }
  }
}

TEST_F(Chc, ChcNeverBlocksWhileTheTraversalQueueHasWork) {
  for (const std::uint32_t interval : {1u, 4u}) {
    for (const int latency : {0, 1, 3, 8, 50}) {
      FakeDevice d(blocks_, latency);
      ChcOptions o;
      o.poll_interval = interval;
      ChcTraversal t(blocks_, o);
      d.watch(&t);
      for (int f = 0; f < 20; ++f) {
        const glm::vec3 eye(-3, -1.0f + 0.1f * f, 0);
        d.set_eye(eye);
        t.frame_render_thread(d, view_from(eye));
      }
      EXPECT_EQ(d.blocked_with_work, 0u) << "latency " << latency << " interval " << interval;
      if (latency >= 8) {
        EXPECT_GT(d.blocking_total, 0u) << "the queue ran dry: some reads block";
      }
      EXPECT_GT(d.polls, 0u);
    }
  }
}

TEST_F(Chc, APollIntervalPollsLessAndClassifiesTheSameOnAStillView) {
  std::uint64_t polls[2];
  std::set<BlockId> drawn[2];
  const std::uint32_t intervals[2] = {1, 6};
  for (int i = 0; i < 2; ++i) {
    FakeDevice d(blocks_, 3);
    ChcOptions o;
    o.poll_interval = intervals[i];
    ChcTraversal t(blocks_, o);
    for (int f = 0; f < 5; ++f) t.frame_render_thread(d, view_from({-3, 0.2f, 0}));
    polls[i] = d.polls;
    drawn[i] = as_set(t.drawn());
    EXPECT_EQ(drawn[i], truth(d));
  }
  EXPECT_LT(polls[1], polls[0]);
}

TEST_F(Chc, ChcIssuesFewerQueriesThanStopAndWaitOnACoherentSequence) {
  std::uint64_t q[2] = {0, 0};
  std::uint64_t waits[2] = {0, 0};
  const OcclusionMode modes[2] = {OcclusionMode::StopAndWait, OcclusionMode::Chc};
  for (int m = 0; m < 2; ++m) {
    FakeDevice d(blocks_, 2);
    ChcTraversal t(blocks_, {modes[m]});
    for (int f = 0; f < 40; ++f) {
      const glm::vec3 eye(-3, -1.0f + 0.05f * f, 0.1f);
      d.set_eye(eye);
      const ChcFrameStats s = t.frame_render_thread(d, view_from(eye));
      q[m] += s.queries;
      waits[m] += s.blocking_reads;
    }
  }
  EXPECT_LT(q[1], q[0]);
  EXPECT_LT(waits[1], waits[0]);
}

TEST_F(Chc, PullDownOpensAnOccludedRegionAndPullUpClosesIt) {
  FakeDevice d(blocks_, 1);
  ChcTraversal t(blocks_, {OcclusionMode::Chc});
  auto run = [&](glm::vec3 eye, int frames) {
    ChcFrameStats s;
    d.set_eye(eye);
    for (int f = 0; f < frames; ++f) s = t.frame_render_thread(d, view_from(eye));
    return s;
  };
  // Close behind the big first sheet: almost everything is hidden.
  const glm::vec3 hidden(-0.6f, 0.0f, 0.0f);
  const glm::vec3 open(-3.0f, 0.0f, 2.5f);
  const ChcFrameStats closed = run(hidden, 3);
  const auto closed_set = as_set(t.visible_leaves());
  EXPECT_EQ(closed_set, truth(d));
  // Which interior blocks are termination nodes (queried, invisible)?
  std::set<BlockId> terminated;
  for (const auto& [b, samples] : d.answers_)
    if (samples == 0) terminated.insert(b);
  EXPECT_FALSE(terminated.empty());
  bool interior_terminated = false;
  for (const BlockId b : terminated) interior_terminated |= !blocks_.is_leaf(b);
  EXPECT_TRUE(interior_terminated) << "the occluded region is closed high in the tree";

  // Pull-down: from above, the region opens; its leaves are found and drawn.
  run(open, 3);
  const auto open_set = as_set(t.visible_leaves());
  EXPECT_EQ(open_set, truth(d));
  EXPECT_GT(open_set.size(), closed_set.size());
  for (const BlockId b : terminated) {
    if (blocks_.is_leaf(b)) continue;
    bool some_leaf_below_visible = false;
    for (const BlockId l : open_set) {
      for (BlockId a = l; a != kNoBlock; a = blocks_.parent(a)) some_leaf_below_visible |= a == b;
    }
    if (some_leaf_below_visible) {
      EXPECT_TRUE(t.visible(b)) << "pulled up from a visible leaf: " << b;
    }
  }
  // Pull-up: back behind the sheet, the open region closes again, and with
  // it the number of queries of a frame returns to that of the closed state.
  const ChcFrameStats again = run(hidden, 3);
  EXPECT_EQ(as_set(t.visible_leaves()), closed_set);
  EXPECT_LE(again.queries, closed.queries + 1);
  for (const BlockId b : terminated) EXPECT_FALSE(t.visible(b)) << b;
}

TEST_F(Chc, AssumeVisibleFramesSkipsQueriesOfVisibleLeavesForTavFrames) {
  FakeDevice d(blocks_, 0);
  ChcOptions o;
  o.assume_visible_frames = 2;
  ChcTraversal t(blocks_, o);
  std::map<BlockId, std::vector<int>> queried_frames;
  std::set<BlockId> seen;
  for (int f = 1; f <= 10; ++f) {
    t.frame_render_thread(d, view_from({-3, 0, 0}));
    for (const BlockId b : d.queried_) queried_frames[b].push_back(f);
    if (f == 1) seen = truth(d);
    EXPECT_EQ(as_set(t.drawn()), seen) << "static view: the visible set, every frame";
  }
  ASSERT_FALSE(seen.empty());
  for (const BlockId b : seen) {
    // Found visible in frame 1 (the first frame queries every termination
    // node); assumed visible in 2 and 3; queried in 4, then 7, 10.
    EXPECT_EQ(queried_frames[b], (std::vector<int>{1, 4, 7, 10})) << "leaf " << b;
  }
  // Invisible termination nodes are queried every frame.
  ChcTraversal exact(blocks_, {OcclusionMode::Chc});
  std::uint64_t q_exact = 0, q_tav = 0;
  for (int f = 0; f < 6; ++f)
    q_exact += exact.frame_render_thread(d, view_from({-3, 0, 0})).queries;
  for (int f = 0; f < 6; ++f) q_tav += t.frame_render_thread(d, view_from({-3, 0, 0})).queries;
  EXPECT_LT(q_tav, q_exact);
}

TEST_F(Chc, MinVisibleSamplesCullsAnswersBelowNvp) {
  FakeDevice d(blocks_, 0);
  // Every answer at or above n_vp opens its block; below it, culls it.
  for (const std::uint64_t nvp : {0ull, 1ull, 5ull, 40ull, 400ull}) {
    for (const OcclusionMode mode : {OcclusionMode::StopAndWait, OcclusionMode::Chc}) {
      ChcOptions o{mode, 0, nvp};
      ChcTraversal t(blocks_, o);
      for (int f = 0; f < 3; ++f) t.frame_render_thread(d, view_from({-3, 0, 0}));
      const auto drawn = as_set(t.drawn());
      const std::uint64_t threshold = std::max<std::uint64_t>(nvp, 1);
      for (const auto& [b, samples] : d.answers_) {
        if (!blocks_.is_leaf(b)) continue;
        EXPECT_EQ(drawn.count(b) == 1, samples >= threshold)
            << "n_vp " << nvp << " block " << b << " samples " << samples;
      }
    }
  }
  // n_vp = 0 and 1 are the exact classification.
  ChcTraversal zero(blocks_, {OcclusionMode::StopAndWait, 0, 0});
  zero.frame_render_thread(d, view_from({-3, 0, 0}));
  ChcTraversal one(blocks_, {OcclusionMode::StopAndWait, 0, 1});
  one.frame_render_thread(d, view_from({-3, 0, 0}));
  EXPECT_EQ(zero.drawn(), one.drawn());
  // A threshold above the screen culls everything at the first queries (the
  // root's box holds the eye: its coarse splats are large, so its children
  // are the first blocks queried).
  ChcTraversal all(blocks_, {OcclusionMode::StopAndWait, 0, kRes * kRes + 1});
  const ChcFrameStats s = all.frame_render_thread(d, view_from({-3, 0, 0}));
  EXPECT_TRUE(all.drawn().empty());
  EXPECT_GT(s.queries, 0u);
  for (const auto& [b, samples] : d.answers_) {
    EXPECT_LT(samples, kRes * kRes + 1u);
    EXPECT_EQ(d.answers_.count(blocks_.parent(b)), 0u) << "nothing below a culled block: " << b;
  }
}

TEST_F(Chc, TheEyeInsideABoxMakesItVisibleWithoutAQuery) {
  FakeDevice d(blocks_, 0);
  ChcTraversal t(blocks_, {OcclusionMode::StopAndWait});
  // Eye inside the root's box: the root is not queried.
  const glm::vec3 eye(-3, 0, 0);
  ViewSnapshot v = view_from(eye);
  v.derived.near_radius = 1e9f;  // every box counts as at the near plane
  const ChcFrameStats s = t.frame_render_thread(d, v);
  EXPECT_EQ(s.queries, 0u);
  EXPECT_GE(t.drawn().size(), leaves_in_frustum(d).size());
}

}  // namespace
