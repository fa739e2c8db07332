// CHC traversal (treecut/culling/chc.hpp) on the CPU device of
// sheets_device.hpp, against its brute-force reference; then the GPU-latency
// model (treecut/culling/gpu_latency.hpp) and CHC++ under it
// (chc_plus_plus.cpp):
//  - the --latency syntax;
//  - LatentOcclusionDevice: an answer is there only the given frames (or
//    microseconds) after its issue; an early read is one blocking read;
//    answers complete in issue order;
//  - CHC++ at 0, 1 and 2 frames: conservative every frame, exact once the
//    view stands, and its only blocking reads are its drains (one per round
//    the frame could not go on without answers), where CHC (the paper's)
//    blocks on nearly every query once answers come a frame late; without
//    waiting it never blocks and draws disocclusions late.
#include <chrono>
#include <stdexcept>
#include <thread>

#include "sheets_device.hpp"
#include "treecut/culling/gpu_latency.hpp"

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

// ---- The GPU-latency model and CHC++ ---------------------------------------

using treecut::culling::GpuLatency;
using treecut::culling::LatentOcclusionDevice;
using treecut::culling::parse_gpu_latency;

TEST(GpuLatencyText, ParsesFramesAndMicroseconds) {
  EXPECT_TRUE(parse_gpu_latency("0").none());
  EXPECT_EQ(parse_gpu_latency("2f").frames, 2u);
  EXPECT_EQ(parse_gpu_latency("1frame").frames, 1u);
  EXPECT_EQ(parse_gpu_latency("3frames").frames, 3u);
  EXPECT_DOUBLE_EQ(parse_gpu_latency("300us").microseconds, 300.0);
  EXPECT_EQ(treecut::culling::describe(parse_gpu_latency("2f")), "2 frames");
  EXPECT_EQ(treecut::culling::describe(parse_gpu_latency("0")), "none");
  for (const char* bad : {"", "f", "-1f", "2", "1.5f", "2x", "1001f", "2e6us", "nanf"}) {
    EXPECT_THROW((void)parse_gpu_latency(bad), std::invalid_argument) << bad;
  }
}

class Latency : public Chc {};

TEST_F(Latency, AnAnswerIsThereOnlyTheGivenFramesAfterItsIssue) {
  FakeDevice inner(blocks_, 0);
  LatentOcclusionDevice d(inner, GpuLatency{2, 0.0});
  d.begin_frame_render_thread();
  const auto q = d.query_box_render_thread(0);
  EXPECT_FALSE(d.result_available_render_thread(q));
  d.end_frame_render_thread(false);
  d.begin_frame_render_thread();
  EXPECT_FALSE(d.result_available_render_thread(q));
  d.end_frame_render_thread(false);
  d.begin_frame_render_thread();
  EXPECT_TRUE(d.result_available_render_thread(q));
  (void)d.result_render_thread(q);
  EXPECT_EQ(d.frame_stats().blocking_reads, 0u);
  d.end_frame_render_thread(false);
}

TEST_F(Latency, AnEarlyReadBlocksOnceAndCompletesTheOlderQueries) {
  FakeDevice inner(blocks_, 0);
  LatentOcclusionDevice d(inner, GpuLatency{1, 0.0});
  d.begin_frame_render_thread();
  const auto older = d.query_box_render_thread(0);
  const auto newer = d.query_box_render_thread(1);
  EXPECT_FALSE(d.result_available_render_thread(older));
  (void)d.result_render_thread(newer);  // waits: the "GPU" finished everything before it
  EXPECT_EQ(d.frame_stats().blocking_reads, 1u);
  EXPECT_TRUE(d.result_available_render_thread(older));
  (void)d.result_render_thread(older);
  EXPECT_EQ(d.frame_stats().blocking_reads, 1u);
  d.end_frame_render_thread(false);
}

TEST_F(Latency, AMicrosecondDelayPassesWithTime) {
  FakeDevice inner(blocks_, 0);
  LatentOcclusionDevice d(inner, GpuLatency{0, 2000.0});
  d.begin_frame_render_thread();
  const auto q = d.query_box_render_thread(0);
  EXPECT_FALSE(d.result_available_render_thread(q));
  std::this_thread::sleep_for(std::chrono::milliseconds(3));
  EXPECT_TRUE(d.result_available_render_thread(q));
  const auto early = d.query_box_render_thread(1);
  (void)d.result_render_thread(early);  // waited out: counted, and its time measured
  EXPECT_EQ(d.frame_stats().blocking_reads, 1u);
  EXPECT_GT(d.frame_stats().wait_ms, 0.0);
  (void)d.result_render_thread(q);
  d.end_frame_render_thread(false);
}

struct WalkCounts {
  std::uint64_t queries = 0, blocking = 0, drains = 0, carried = 0;
};

// The walk of ChcIsConservativeEveryFrameAndExactOnceTheViewStops: moving for
// 20 frames, then standing; every frame conservative, exact from `exact_from`.
WalkCounts walk(const Chc& fixture, const HlodBlocks& blocks, ChcOptions options,
                std::uint32_t latency_frames, int exact_from) {
  FakeDevice inner(blocks, 0);
  LatentOcclusionDevice d(inner, GpuLatency{latency_frames, 0.0});
  ChcTraversal t(blocks, options);
  WalkCounts c;
  for (int f = 0; f < 32; ++f) {
    const float y = f < 20 ? -1.5f + 0.15f * f : 1.5f;
    inner.set_eye({-3, y, 0.2f});
    const ChcFrameStats s = t.frame_render_thread(d, view_from({-3, y, 0.2f}));
    const auto seen = fixture.truth_of(inner);
    const auto drawn = std::set<BlockId>(t.drawn().begin(), t.drawn().end());
    for (const BlockId b : seen) {
      EXPECT_TRUE(drawn.count(b)) << "latency " << latency_frames << " frame " << f << " culled "
                                  << b;
    }
    if (f >= exact_from) {
      EXPECT_EQ(drawn, seen) << "latency " << latency_frames << " frame " << f;
    }
    c.queries += s.queries;
    c.blocking += s.blocking_reads;
    c.drains += s.drains;
    c.carried += s.carried_answers;
  }
  t.release_render_thread(d);
  return c;
}

TEST_F(Latency, ChcPlusPlusIsConservativeAndBlocksOnlyInItsDrains) {
  for (const std::uint32_t frames : {0u, 1u, 2u}) {
    const WalkCounts pp =
        walk(*this, blocks_, {OcclusionMode::ChcPlusPlus}, frames, 22 + int(frames));
    const WalkCounts chc = walk(*this, blocks_, {OcclusionMode::Chc}, frames, 22);
    EXPECT_GT(pp.queries, 0u);
    EXPECT_GT(pp.carried, 0u) << "visible leaves' answers are taken in later frames";
    // Every blocking read is a drain's (the traversal had nothing else to
    // do), at most one per drain.
    EXPECT_LE(pp.blocking, pp.drains) << frames;
    if (frames > 0) {
      // The paper's CHC reads most answers in the frame they were issued
      // in: under a frame of latency, each is a blocking read.
      EXPECT_GE(chc.blocking, chc.queries / 2) << frames;
      EXPECT_LT(5 * pp.blocking, chc.blocking) << frames;
    } else {
      EXPECT_EQ(pp.blocking, 0u);
    }
  }
}

TEST_F(Latency, RandomizedAssumedVisibilitySpreadsTheQueriesOfVisibleLeaves) {
  FakeDevice inner(blocks_, 0);
  LatentOcclusionDevice d(inner, GpuLatency{1, 0.0});
  ChcOptions o{OcclusionMode::ChcPlusPlus};
  o.assume_visible_frames = 4;
  ChcTraversal t(blocks_, o);
  std::vector<std::uint64_t> queries;
  for (int f = 0; f < 16; ++f) queries.push_back(t.frame_render_thread(d, view_from({-3, 0.2f, 0})).queries);
  ChcTraversal every(blocks_, {OcclusionMode::ChcPlusPlus});
  std::uint64_t all = 0, fewer = 0;
  for (int f = 0; f < 16; ++f) {
    all += every.frame_render_thread(d, view_from({-3, 0.2f, 0})).queries;
    if (f >= 4) fewer += queries[std::size_t(f)];
  }
  EXPECT_EQ(std::set<BlockId>(t.drawn().begin(), t.drawn().end()), truth_of(inner));
  EXPECT_LT(fewer, all * 12 / 16) << "t_av = 4 skips queries of visible leaves";
  EXPECT_GT(fewer, 0u) << "and still queries some every few frames";
  t.release_render_thread(d);
  every.release_render_thread(d);
}

TEST_F(Latency, ChcPlusPlusWithoutWaitingNeverBlocksAndDrawsDisocclusionsLate) {
  for (const std::uint32_t frames : {1u, 2u}) {
    FakeDevice inner(blocks_, 0);
    LatentOcclusionDevice d(inner, GpuLatency{frames, 0.0});
    ChcOptions o{OcclusionMode::ChcPlusPlus};
    o.wait_for_invisible = false;
    ChcTraversal t(blocks_, o);
    std::uint64_t blocking = 0, delayed = 0, missed_frames = 0;
    for (int f = 0; f < 32; ++f) {
      const float y = f < 20 ? -1.5f + 0.15f * f : 1.5f;
      inner.set_eye({-3, y, 0.2f});
      const ChcFrameStats s = t.frame_render_thread(d, view_from({-3, y, 0.2f}));
      blocking += s.blocking_reads;
      delayed += s.delayed_blocks;
      const auto seen = truth_of(inner);
      const std::set<BlockId> drawn(t.drawn().begin(), t.drawn().end());
      bool missed = false;
      for (const BlockId b : seen) missed = missed || drawn.count(b) == 0;
      missed_frames += missed ? 1 : 0;
      // Standing still, it catches up: exact within a few frames.
      if (f >= 24 + 2 * int(frames)) {
        EXPECT_EQ(drawn, seen) << "latency " << frames << " frame " << f;
      }
    }
    t.release_render_thread(d);
    EXPECT_EQ(blocking, 0u) << frames;
    EXPECT_GT(delayed, 0u) << "the walk disoccludes blocks, drawn late: " << frames;
    EXPECT_GT(missed_frames, 0u) << "the price: frames missing a visible block: " << frames;
  }
}

}  // namespace
