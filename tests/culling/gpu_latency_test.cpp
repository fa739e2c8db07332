// The GPU-latency model (treecut/culling/gpu_latency.hpp) and CHC++ under it
// (chc_plus_plus.cpp), on the CPU device of sheets_device.hpp:
//  - the --latency syntax;
//  - LatentOcclusionDevice: an answer is there only the given frames (or
//    microseconds) after its issue; an early read is one blocking read;
//    answers complete in issue order;
//  - CHC++ at 0, 1 and 2 frames: conservative every frame, exact once the
//    view stands, and its only blocking reads are its drains (one per round
//    the frame could not go on without answers), where CHC (the paper's)
//    blocks on nearly every query once answers come a frame late.
#include "treecut/culling/gpu_latency.hpp"

#include <chrono>
#include <stdexcept>
#include <thread>

#include "sheets_device.hpp"

namespace {

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
