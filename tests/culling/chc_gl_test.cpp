// CHC on the GL device (splat/occlusion_device_gl.hpp, strategies/chc.hpp) on
// OSMesa, on small generated scenes with their walkthroughs:
//  - nothing visible is culled under exact settings (t_av = 0, n_vp = 0):
//    every leaf block in the frustum that CHC does not draw is hidden to a
//    brute-force reference (drawn inside a query after every other leaf
//    block in the frustum: no sample passes), frame after frame along the
//    walkthrough, on the binary tree of blocks CHC runs on;
//  - the render thread reads GL_QUERY_RESULT only after
//    GL_QUERY_RESULT_AVAILABLE said true for that query, or in a read the
//    device counts as a blocking wait (interposed entry points; availability
//    is hidden from the device for a while to make the check live);
//  - no GL object is made per frame once the pool is warm;
//  - `treecut bench occlusion`: the table's rows, and bad input refused with
//    one line and exit code 2.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "query_check.hpp"
#include "test_support.hpp"
#include "treecut/attributes.hpp"
#include "treecut/culling/chc.hpp"
#include "treecut/culling/gpu_latency.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/gl.hpp"
#include "treecut/splat/occlusion_device_gl.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::splat {
namespace {

using culling::BlockId;
using culling::ChcFrameStats;
using culling::ChcOptions;
using culling::ChcTraversal;
using culling::HlodBlocks;
using culling::OcclusionMode;

constexpr int kWidth = 320;
constexpr int kHeight = 180;

struct SceneCase {
  tools::ModelKind kind;
  std::size_t points;
};

std::shared_ptr<const Hierarchy> scene(tools::ModelKind kind, std::size_t points) {
  static std::map<int, std::shared_ptr<const Hierarchy>> cache;
  auto& slot = cache[static_cast<int>(kind)];
  if (!slot) {
    PointSet ps = kind == tools::ModelKind::City ? tools::generate_city(points, 5)
                                                 : tools::generate_plant(points, 5);
    complete_attributes(ps);
    slot = std::make_shared<const Hierarchy>(build_hierarchy(std::move(ps)));
  }
  return slot;
}

// Frames of the walkthrough: `count` times spread over it (overview, descent,
// street level, ascent).
std::vector<Camera> walk_cameras(tools::ModelKind kind, const Hierarchy& h, int count) {
  const auto keys = tools::scene_walkthrough(kind);
  const glm::vec3 center = 0.5f * (h.bounds_min() + h.bounds_max());
  const float radius = 0.5f * glm::length(h.bounds_max() - h.bounds_min());
  std::vector<Camera> out;
  for (int i = 0; i < count; ++i) {
    const tools::WalkKey& k =
        keys[(keys.size() - 1) * static_cast<std::size_t>(i) / static_cast<std::size_t>(count - 1)];
    Camera c;
    c.eye = k.eye, c.target = k.target, c.up = k.up, c.fov_y_deg = k.fov_deg;
    fit_clip_planes(c, center, radius);
    out.push_back(c);
  }
  return out;
}

class ChcGl : public ::testing::TestWithParam<SceneCase> {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  void SetUp() override {
    h_ = scene(GetParam().kind, GetParam().points);
    blocks_ = HlodBlocks::build(*h_, 500, culling::kBinaryFanOut);
    renderer_ = std::make_unique<Renderer>(*h_, glm::ivec2(kWidth, kHeight));
    device_ = std::make_unique<GlOcclusionDevice>(*renderer_, blocks_);
  }

  // The leaf blocks in the frustum (VFC's set).
  std::vector<BlockId> in_frustum(const Camera& c) {
    ChcTraversal vfc(blocks_, {OcclusionMode::Vfc});
    device_->set_view_render_thread(c, settings_);
    vfc.frame_render_thread(*device_, c.view({kWidth, kHeight}));
    return vfc.drawn();
  }
  // The reference: each leaf block of `candidates` drawn inside a query after
  // every other leaf block in the frustum (`in`); visible if any of its
  // samples passed.
  std::set<BlockId> reference(const Camera& c, const std::vector<BlockId>& in,
                              const std::vector<BlockId>& candidates) {
    device_->set_view_render_thread(c, settings_);
    std::set<BlockId> seen;
    for (const BlockId b : candidates) {
      device_->begin_frame_render_thread();
      for (const BlockId o : in) {
        if (o != b) device_->draw_render_thread(o);
      }
      const auto q = device_->query_draw_render_thread(b);
      if (device_->result_render_thread(q) > 0) seen.insert(b);
      device_->end_frame_render_thread(false);
    }
    return seen;
  }

  std::shared_ptr<const Hierarchy> h_;
  HlodBlocks blocks_;
  std::unique_ptr<Renderer> renderer_;
  std::unique_ptr<GlOcclusionDevice> device_;
  RenderSettings settings_;
};

// Only the blocks CHC culls are given to the reference: a visible block is
// missed exactly when one of them is seen, so the check is the same as
// classifying every block in the frustum, at the cost of the culled ones
// alone (the reference costs a frame per block; the run took 106 s for the
// city and 96 s for the plant under load 15 when it classified them all).
TEST_P(ChcGl, NothingVisibleIsCulledUnderExactSettings) {
  const auto cameras = walk_cameras(GetParam().kind, *h_, 7);
  ChcTraversal chc(blocks_, {OcclusionMode::Chc, 0, 0});
  std::size_t occluded_frames = 0, reference_frames = 0, all_frames = 0;
  for (std::size_t f = 0; f < cameras.size(); ++f) {
    const std::vector<BlockId> in = in_frustum(cameras[f]);
    device_->set_view_render_thread(cameras[f], settings_);
    const ChcFrameStats s =
        chc.frame_render_thread(*device_, cameras[f].view({kWidth, kHeight}));
    const std::set<BlockId> drawn(chc.drawn().begin(), chc.drawn().end());
    std::vector<BlockId> culled;
    for (const BlockId b : in)
      if (drawn.count(b) == 0) culled.push_back(b);
    const std::set<BlockId> missed = reference(cameras[f], in, culled);
    EXPECT_TRUE(missed.empty()) << "frame " << f << ": " << missed.size() << " of " << culled.size()
                                << " culled leaf blocks are visible";
    EXPECT_EQ(s.blocks_drawn, drawn.size());
    // And the reference can see: of the first three blocks CHC drew (the
    // nearest, front to back), one at least is visible to it.
    const std::vector<BlockId> first(
        chc.drawn().begin(), chc.drawn().begin() + std::min<std::ptrdiff_t>(3, chc.drawn().size()));
    if (!first.empty()) {
      EXPECT_FALSE(reference(cameras[f], in, first).empty()) << "frame " << f;
    }
    // The check has teeth: the street frames cull (and the reference
    // confirms hidden) a third or more of what is in the frustum (measured:
    // city 21 of 39 and 20 of 39, plant 16 of 42, 16 of 39 and 15 of 33).
    if (culled.size() * 3 >= in.size() && !culled.empty()) ++occluded_frames;
    std::printf("frame %zu: %zu of %zu culled\n", f, culled.size(), in.size());
    reference_frames += culled.size();
    all_frames += in.size();
  }
  EXPECT_GE(occluded_frames, 2u);
  EXPECT_GE(reference_frames, 30u);
  std::printf("reference: %zu frames of %zu leaf blocks in the frustum\n", reference_frames,
              all_frames);
}

// CHC++ (chc_plus_plus.cpp) under the GPU-latency model at 0, 1 and 2
// frames: conservative every frame of the walk (the reference finds none of
// the blocks it culls visible), and its only blocking reads are its drains.
TEST_P(ChcGl, ChcPlusPlusCullsNothingVisibleUnderGpuLatency) {
  const auto cameras = walk_cameras(GetParam().kind, *h_, 5);
  for (const std::uint32_t frames : {0u, 1u, 2u}) {
    culling::LatentOcclusionDevice latent(*device_, {frames, 0.0});
    ChcTraversal chc(blocks_, {OcclusionMode::ChcPlusPlus});
    std::uint64_t queries = 0, blocking = 0, drains = 0, culled_total = 0;
    for (std::size_t f = 0; f < cameras.size(); ++f) {
      const std::vector<BlockId> in = in_frustum(cameras[f]);
      device_->set_view_render_thread(cameras[f], settings_);
      const ChcFrameStats s = chc.frame_render_thread(latent, cameras[f].view({kWidth, kHeight}));
      const std::set<BlockId> drawn(chc.drawn().begin(), chc.drawn().end());
      std::vector<BlockId> culled;
      for (const BlockId b : in)
        if (drawn.count(b) == 0) culled.push_back(b);
      EXPECT_TRUE(reference(cameras[f], in, culled).empty())
          << "latency " << frames << " frame " << f;
      queries += s.queries, blocking += s.blocking_reads, drains += s.drains;
      culled_total += culled.size();
    }
    chc.release_render_thread(latent);
    EXPECT_GT(queries, 0u);
    EXPECT_GT(culled_total, 15u) << "the walk has occlusion to find";
    EXPECT_LE(blocking, drains) << frames;
  }
}

TEST_P(ChcGl, StopAndWaitAndIdealDrawTheSameSetAndChcConvergesToIt) {
  const Camera c = walk_cameras(GetParam().kind, *h_, 9)[4];  // street level
  const auto view = c.view({kWidth, kHeight});
  device_->set_view_render_thread(c, settings_);
  ChcTraversal sw(blocks_, {OcclusionMode::StopAndWait});
  const ChcFrameStats s = sw.frame_render_thread(*device_, view);
  EXPECT_GT(s.queries, 0u);
  ChcTraversal ideal(blocks_, {OcclusionMode::Ideal});
  ideal.set_ideal_leaves(sw.drawn());
  const ChcFrameStats i = ideal.frame_render_thread(*device_, view);
  EXPECT_EQ(ideal.drawn(), sw.drawn());
  EXPECT_EQ(i.queries, 0u);
  EXPECT_EQ(i.splats_drawn, s.splats_drawn);
  ChcTraversal chc(blocks_, {OcclusionMode::Chc});
  ChcFrameStats last;
  for (int f = 0; f < 4; ++f) last = chc.frame_render_thread(*device_, view);
  // A static view: the S&W classification (the paper, section 3.4).
  const std::set<BlockId> a(chc.drawn().begin(), chc.drawn().end());
  const std::set<BlockId> b(sw.drawn().begin(), sw.drawn().end());
  EXPECT_EQ(a, b);
  EXPECT_LT(last.queries, s.queries);
}

INSTANTIATE_TEST_SUITE_P(Scenes, ChcGl,
                         ::testing::Values(SceneCase{tools::ModelKind::City, 40000},
                                           SceneCase{tools::ModelKind::Plant, 40000}),
                         [](const auto& p) {
                           return p.param.kind == tools::ModelKind::City ? "city" : "plant";
                         });

using test::QueryCheck;  // tests/support/query_check.hpp

class ChcGlQueries : public ChcGl {};

TEST_P(ChcGlQueries, NeverReadsAResultBeforeItWasSeenAvailableUnlessItCountsTheWait) {
  const auto cameras = walk_cameras(GetParam().kind, *h_, 12);
  for (const OcclusionMode mode : {OcclusionMode::Chc, OcclusionMode::StopAndWait}) {
    ChcTraversal t(blocks_, {mode});
    // Warm: the pool has grown to what the walk needs.
    for (const Camera& c : cameras) {
      device_->set_view_render_thread(c, settings_);
      t.frame_render_thread(*device_, c.view({kWidth, kHeight}), false);
    }
    t.reset();
    const QueryCheck check;
    std::uint64_t blocking = 0, queries = 0;
    for (const Camera& c : cameras) {
      device_->set_view_render_thread(c, settings_);
      const ChcFrameStats s =
          t.frame_render_thread(*device_, c.view({kWidth, kHeight}), false);
      blocking += s.blocking_reads;
      queries += s.queries;
    }
    EXPECT_GT(queries, 0u);
    EXPECT_EQ(static_cast<std::uint64_t>(QueryCheck::reads), queries);
    // Every read before availability was seen is a wait the device counted.
    EXPECT_EQ(static_cast<std::uint64_t>(QueryCheck::early_reads), blocking)
        << occlusion_mode_name(mode);
    if (mode == OcclusionMode::StopAndWait) {
      EXPECT_EQ(blocking, queries) << "stop-and-wait waits for every answer it could not see";
    } else {
      EXPECT_GT(QueryCheck::hidden, 0) << "the check hid available results";
      EXPECT_LT(blocking, queries) << "CHC reads answers after polling them";
    }
    EXPECT_EQ(QueryCheck::created, 0) << "no query object made per frame";
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, ChcGlQueries,
                         ::testing::Values(SceneCase{tools::ModelKind::City, 40000}),
                         [](const auto&) { return "city"; });

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(BenchOcclusion, PrintsTheChcTableOfAWalk) {
  const auto dir = test::scratch_dir("bench_occlusion");
  const auto model = dir / "city.ply";
  ASSERT_EQ(test::run_treecut("gen city -n 20000 -o " + test::quote(model)).code, 0);
  const std::string walk =
      test::quote(std::filesystem::path(TREECUT_SOURCE_DIR) / "assets/paths/city_walk.campath");
  const auto r = test::run_treecut("bench occlusion " + test::quote(model) + " --path " + walk +
                                   " --frames 3 --width 160 --height 90 --block-size 200"
                                   " --compare-fan-out 4 --latency 1f");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("\nlatency   1 frame (GPU-latency model"), std::string::npos) << r.out;
  EXPECT_EQ(count(r.out, "| VFC | 0 | 0 |"), 1) << r.out;
  EXPECT_EQ(count(r.out, "| S&W | 0 | 0 |"), 1);
  EXPECT_EQ(count(r.out, "| CHC | 0 | 0 |"), 1);
  EXPECT_EQ(count(r.out, "| Ideal | 0 | 0 |"), 1);
  EXPECT_EQ(count(r.out, "| CHC | 2 | 0 |"), 1);
  EXPECT_EQ(count(r.out, "| CHC | 0 | 25 |"), 1);
  EXPECT_EQ(count(r.out, "| CHC++ | 0 | 0 |"), 1);
  EXPECT_EQ(count(r.out, "| CHC++ | 4 | 0 |"), 1);
  EXPECT_NE(r.out.find("3 frames"), std::string::npos) << r.out;
  // The 4-ary tree's rows beside the binary tree's, in the same run.
  EXPECT_NE(r.out.find("fan-out 2, built"), std::string::npos) << r.out;
  for (const char* m : {"VFC", "S&W", "CHC", "Ideal"}) {
    EXPECT_EQ(count(r.out, std::string("| ") + m + ", fan-out 4 | 0 | 0 |"), 1) << m;
  }
  // Both speed-ups, each against the VFC row of its own tree: 1 for VFC itself.
  EXPECT_NE(r.out.find("| speed-up vs VFC (ratio of means) | speed-up vs VFC (mean per frame, "
                       "the paper's) | delayed blocks |\n"),
            std::string::npos)
      << r.out;
  for (const char* vfc : {"| VFC | 0 | 0 |", "| VFC, fan-out 4 | 0 | 0 |"}) {
    const std::size_t at = r.out.find(vfc);
    ASSERT_NE(at, std::string::npos) << vfc;
    const std::string line = r.out.substr(at, r.out.find('\n', at) - at);
    EXPECT_TRUE(line.ends_with("| 1.00 | 1.00 | --- |")) << line;
  }
}

TEST(BenchOcclusion, RefusesBadInputWithOneLineAndExitCode2) {
  const auto dir = test::scratch_dir("bench_occlusion_bad");
  const std::string walk =
      test::quote(std::filesystem::path(TREECUT_SOURCE_DIR) / "assets/paths/city_walk.campath");
  const auto missing =
      test::run_treecut("bench occlusion " + test::quote(dir / "none.ply") + " --path " + walk);
  EXPECT_EQ(missing.code, 2);
  EXPECT_EQ(missing.out, "treecut: " + (dir / "none.ply").string() + ": no such file\n");
  const auto fifo = dir / "fifo";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const auto r = test::run_treecut("bench occlusion " + test::quote(fifo) + " --path " + walk, 20);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "treecut: " + fifo.string() + ": is a FIFO, not a regular file\n");
  const auto no_path = test::run_treecut("bench occlusion " + test::quote(dir / "none.ply") +
                                         " --path " + test::quote(dir / "none.campath"));
  EXPECT_EQ(no_path.code, 2);
  EXPECT_EQ(count(no_path.out, "\n"), 1) << no_path.out;
  EXPECT_NE(no_path.out.find("none.campath"), std::string::npos) << no_path.out;
  // Fan-outs other than 2 and 4, or the same tree twice, before any work.
  const auto model = dir / "m.ply";
  ASSERT_EQ(test::run_treecut("gen city -n 2000 -o " + test::quote(model)).code, 0);
  for (const char* bad : {"--block-fan-out 3", "--compare-fan-out 2", "--compare-fan-out 5"}) {
    const auto b =
        test::run_treecut("bench occlusion " + test::quote(model) + " --path " + walk + " " + bad);
    EXPECT_EQ(b.code, 2) << bad;
    EXPECT_EQ(count(b.out, "\n"), 1) << b.out;
    EXPECT_NE(b.out.find("fan-out"), std::string::npos) << b.out;
  }
  const auto latency = test::run_treecut("bench occlusion " + test::quote(model) + " --path " +
                                         walk + " --latency 3x");
  EXPECT_EQ(latency.code, 2);
  EXPECT_EQ(latency.out,
            "treecut: --latency: latency '3x': the unit is f (frames) or us (microseconds) "
            "(examples: 0, 1f, 2frames, 300us)\n");
}

}  // namespace
}  // namespace treecut::splat
