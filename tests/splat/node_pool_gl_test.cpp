// GpuNodePool on OSMesa (issue 45): a paged model's lists drawn from a pool
// of vertices within a GPU budget. With every page the list needs up, the
// image is the one of the model held whole, pixel for pixel; pages come up
// a few a frame within the upload budget, the list drawn meanwhile with
// ancestors standing in; the budget holds in every frame, and pages no list
// uses are given back.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "strategy_fixtures.hpp"
#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/node_pool.hpp"
#include "treecut/splat/renderer.hpp"

namespace treecut::splat {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 200;
constexpr int kHeight = 150;

class NodePool : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  void SetUp() override {
    // A terrain of 100,000 points: some twenty pages.
    // One folder a test: CTest runs them as parallel processes.
    const fs::path dir =
        test::scratch_dir(std::string("node_pool_") +
                          ::testing::UnitTest::GetInstance()->current_test_info()->name());
    cache_ = dir / "t.tch";
    save_cache(*test::small_hierarchy(tools::ModelKind::Terrain, 100000), {1, 2, 3}, cache_);
    std::string why;
    whole_ = load_cache(cache_, std::nullopt, &why);
    ASSERT_TRUE(whole_) << why;
    paged_ = PagedHierarchy::open(cache_);
    test::load_every_page(*paged_);
    camera_ = default_camera(whole_->bounds_min(), whole_->bounds_max(), float(kWidth) / kHeight);
  }

  // The nodes of level D whose centre lies where KEEP says (x of it).
  std::vector<NodeId> level(int d, bool (*keep)(float) = nullptr) const {
    std::vector<NodeId> v;
    for (NodeId n = whole_->level_begin(d); n < whole_->level_begin(d + 1); ++n)
      if (keep == nullptr || keep(whole_->center(n).x)) v.push_back(n);
    return v;
  }
  // The image of IDS drawn from the model held whole.
  Image whole_image(const std::vector<NodeId>& ids) {
    Renderer r(*whole_, {kWidth, kHeight});
    CutBuffer cut;
    cut.upload(*whole_, ids);
    r.draw(cut, camera_, RenderSettings{}, true);
    return Image{kWidth, kHeight, r.read_pixels()};
  }
  // Pixels that differ from the background.
  static std::size_t drawn(const Image& image) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < image.rgba.size(); i += 4)
      n += image.rgba[i] != image.rgba[0] || image.rgba[i + 1] != image.rgba[1] ||
           image.rgba[i + 2] != image.rgba[2];
    return n;
  }

  // A pooled renderer and its pool, and the frames drawn through them.
  struct Pooled {
    Pooled(const PagedHierarchy& paged, const GpuPoolOptions& o)
        : renderer(paged.hierarchy(), {kWidth, kHeight}, GpuNodePool::segment_vertices(paged, o)),
          pool(renderer, paged, o) {
      cut.set_vertex_map(&pool);
    }
    // One frame: IDS uploaded when given (a new list), pages copied up, drawn.
    Image frame(const Hierarchy& h, const Camera& camera, const std::vector<NodeId>* ids) {
      pool.begin_frame();
      if (ids != nullptr) cut.upload(h, *ids);
      pool.prepare(cut);
      renderer.draw(cut, camera, RenderSettings{}, true);
      return Image{kWidth, kHeight, renderer.read_pixels()};
    }
    Renderer renderer;
    GpuNodePool pool;
    CutBuffer cut;
  };

  fs::path cache_;
  std::optional<Hierarchy> whole_;
  std::unique_ptr<PagedHierarchy> paged_;
  Camera camera_;
};

std::set<std::uint32_t> page_set(const PagedHierarchy& paged, const std::vector<NodeId>& ids) {
  std::set<std::uint32_t> pages;
  for (const NodeId n : ids) pages.insert(paged.page_of(n));
  return pages;
}

std::size_t pages_of(const PagedHierarchy& paged, const std::vector<NodeId>& ids) {
  return page_set(paged, ids).size();
}

// The pool's blocks the pages of IDS take.
std::uint64_t blocks_of(const PagedHierarchy& paged, const std::vector<NodeId>& ids) {
  std::uint64_t blocks = 0;
  for (const std::uint32_t p : page_set(paged, ids))
    blocks += (paged.page_nodes(p) + GpuNodePool::kBlock - 1) / GpuNodePool::kBlock;
  return blocks;
}

}  // namespace

TEST_F(NodePool, EveryPageUpDrawsTheImageOfTheModelHeldWhole) {
  const std::vector<NodeId> ids = level(whole_->level_count() - 2);
  ASSERT_GT(pages_of(*paged_, ids), 4u);
  const Image expected = whole_image(ids);
  Pooled p(*paged_, {64u << 20, 64u << 20});
  const Image got = p.frame(paged_->hierarchy(), camera_, &ids);
  const GpuPoolStats s = p.pool.stats();
  EXPECT_EQ(s.stand_ins, 0u);
  EXPECT_EQ(s.waiting_pages, 0u);
  EXPECT_GT(s.uploaded_bytes, ids.size() * GpuNodePool::kVertexBytes);
  EXPECT_EQ(s.resident_pages, pages_of(*paged_, ids) + 1);  // and the root's page
  EXPECT_GT(drawn(got), std::size_t{kWidth * kHeight / 10});
  EXPECT_TRUE(got.rgba == expected.rgba) << "the pooled frame differs from the whole model's";
}

// A cut through the middle of pages needs their levels down to its own,
// not the pages' deeper levels, which hold most of their nodes.
TEST_F(NodePool, ACutThroughPagesTakesTheirLevelsDownToItsOwn) {
  // The deepest level whose nodes all lie above the pages' last levels.
  const std::vector<NodeId> ids = level(whole_->level_count() - 5);
  ASSERT_GT(pages_of(*paged_, ids), 1u);
  Pooled p(*paged_, {64u << 20, 64u << 20});
  const Image got = p.frame(paged_->hierarchy(), camera_, &ids);
  const GpuPoolStats s = p.pool.stats();
  EXPECT_EQ(s.stand_ins, 0u);
  std::vector<NodeId> with_root = ids;
  with_root.push_back(0);
  const std::uint64_t whole_pages =
      blocks_of(*paged_, with_root) * GpuNodePool::kBlock * GpuNodePool::kVertexBytes;
  EXPECT_LT(s.resident_bytes, whole_pages) << "whole pages up for a cut through them";
  EXPECT_TRUE(got.rgba == whole_image(ids).rgba);
}

// The pool starts as one segment and a segment more as the pages need,
// within the budget; the vertices already up stay where they are (the
// lists' indices hold), and a list over several segments draws as the
// model held whole does, fading too.
TEST_F(NodePool, ThePoolGrowsBySegmentsKeepingWhatIsUp) {
  const std::vector<NodeId> coarse = level(whole_->level_count() - 5);
  const std::vector<NodeId> fine = level(whole_->level_count() - 2);
  GpuPoolOptions o{64u << 20, 64u << 20};
  o.segment_bytes = 1;  // the least: a block
  Pooled p(*paged_, o);
  const GpuPoolStats first = p.pool.stats();
  EXPECT_EQ(first.allocated_bytes,
            first.segments * GpuNodePool::kBlock * GpuNodePool::kVertexBytes);
  Image got = p.frame(paged_->hierarchy(), camera_, &coarse);
  for (int f = 0; f < 200 && p.pool.stats().waiting_pages > 0; ++f)
    got = p.frame(paged_->hierarchy(), camera_, nullptr);
  EXPECT_TRUE(got.rgba == whole_image(coarse).rgba);
  got = p.frame(paged_->hierarchy(), camera_, &fine);
  for (int f = 0; f < 200 && p.pool.stats().waiting_pages > 0; ++f) {
    const std::uint64_t segments = p.pool.stats().segments;
    got = p.frame(paged_->hierarchy(), camera_, nullptr);
    // One request a frame: a page's blocks (a page is 8 blocks at most).
    EXPECT_LE(p.pool.stats().segments - segments, 8u) << "frame " << f;
  }
  const GpuPoolStats s = p.pool.stats();
  EXPECT_EQ(s.waiting_pages, 0u);
  EXPECT_GT(s.segments, first.segments);
  EXPECT_EQ(p.renderer.segments(), s.segments);
  EXPECT_GT(s.allocated_bytes, first.allocated_bytes);
  EXPECT_LE(s.allocated_bytes, s.capacity_bytes);
  EXPECT_LE(s.resident_bytes, s.allocated_bytes);
  EXPECT_EQ(s.evictions, 0u) << "pages given back while the budget had room";
  EXPECT_EQ(s.stand_ins, 0u);
  ASSERT_GT(p.cut.segment_runs().size(), 1u);
  EXPECT_TRUE(got.rgba == whole_image(fine).rgba);
  const FrameStats drawn_stats = p.renderer.draw(p.cut, camera_, RenderSettings{}, true);
  EXPECT_EQ(drawn_stats.draw_calls, p.cut.segment_runs().size());
  EXPECT_EQ(drawn_stats.splats, fine.size());

  // A fade from the fine list back to the coarse one, halfway: the three
  // runs, each over its segments, as the model held whole draws them.
  Renderer whole(*whole_, {kWidth, kHeight});
  CutBuffer whole_cut;
  whole_cut.upload(*whole_, coarse, fine);
  whole_cut.set_fade(0.5f);
  whole.draw(whole_cut, camera_, RenderSettings{}, true);
  p.pool.begin_frame();
  p.cut.upload(paged_->hierarchy(), coarse, fine);
  p.cut.set_fade(0.5f);
  p.pool.prepare(p.cut);
  EXPECT_EQ(p.pool.stats().waiting_pages, 0u);
  p.renderer.draw(p.cut, camera_, RenderSettings{}, true);
  EXPECT_TRUE(p.renderer.read_pixels() == whole.read_pixels()) << "the fade differs";
  // Positions are the segments' now, not the ids': no ranges of them.
  const CutRange all{0, static_cast<std::uint32_t>(p.cut.size())};
  EXPECT_THROW(p.renderer.draw_ranges(p.cut, {&all, 1}, camera_, RenderSettings{}),
               std::logic_error);
}

TEST_F(NodePool, PagesComeUpAFewAFrameWithinTheBudgetsAncestorsStandingIn) {
  const std::vector<NodeId> ids = level(whole_->level_count() - 2);
  const Image expected = whole_image(ids);
  // Room for every page; one page a frame (an upload budget of a byte).
  Pooled p(*paged_, {64u << 20, 1});
  Image got = p.frame(paged_->hierarchy(), camera_, &ids);
  GpuPoolStats s = p.pool.stats();
  EXPECT_GT(s.stand_ins, 0u) << "every page up in the first frame";
  EXPECT_GT(drawn(got), 0u) << "nothing drawn while the pages come up";
  int frames = 1;
  std::uint64_t uploads = s.uploads;
  for (; frames < 200 && p.pool.stats().waiting_pages > 0; ++frames) {
    got = p.frame(paged_->hierarchy(), camera_, nullptr);
    s = p.pool.stats();
    EXPECT_LE(s.uploads - uploads, 1u) << "frame " << frames;
    EXPECT_LE(s.uploaded_bytes, 8192u * GpuNodePool::kVertexBytes);
    EXPECT_GT(drawn(got), 0u) << "frame " << frames;
    uploads = s.uploads;
  }
  EXPECT_EQ(s.waiting_pages, 0u);
  EXPECT_GE(static_cast<std::size_t>(frames), pages_of(*paged_, ids) - 1);
  EXPECT_EQ(s.stand_ins, 0u);
  EXPECT_TRUE(got.rgba == expected.rgba) << "once every page is up the image differs";
}

TEST_F(NodePool, TheBudgetHoldsAndPagesNoListUsesAreGivenBack) {
  const int d = whole_->level_count() - 2;
  const std::vector<NodeId> left = level(d, [](float x) { return x < -0.2f; });
  const std::vector<NodeId> right = level(d, [](float x) { return x > 0.2f; });
  // Room for the root's page and the larger half's pages, a block more:
  // not for both halves.
  const std::uint64_t l = blocks_of(*paged_, left), r = blocks_of(*paged_, right);
  ASSERT_GT(std::min(l, r), 1u);
  const std::uint64_t root = blocks_of(*paged_, {0});
  const std::uint64_t budget =
      (root + std::max(l, r) + 1) * GpuNodePool::kBlock * GpuNodePool::kVertexBytes;
  Pooled p(*paged_, {budget, 64u << 20});
  p.frame(paged_->hierarchy(), camera_, &left);
  EXPECT_EQ(p.pool.stats().waiting_pages, 0u);
  EXPECT_EQ(p.pool.stats().evictions, 0u);
  const Image got = p.frame(paged_->hierarchy(), camera_, &right);
  GpuPoolStats s = p.pool.stats();
  EXPECT_GT(s.evictions, 0u) << "the left half's pages were not given back";
  EXPECT_EQ(s.waiting_pages, 0u);
  EXPECT_LE(s.resident_bytes, s.capacity_bytes);
  EXPECT_LE(s.capacity_bytes, budget);
  EXPECT_TRUE(got.rgba == whole_image(right).rgba);
  // And back: the left half comes up again, its slots where the right
  // half's went back (the memory pages they share counted: one given back
  // too early reads as zeros, a node drawn as its ancestor).
  const Image again = p.frame(paged_->hierarchy(), camera_, &left);
  s = p.pool.stats();
  EXPECT_EQ(s.waiting_pages, 0u);
  EXPECT_LE(s.resident_bytes, s.capacity_bytes);
  EXPECT_EQ(s.stand_ins, 0u);
  EXPECT_TRUE(again.rgba == whole_image(left).rgba);
  // The slots' memory pages: those of the pages up, not the model's.
  EXPECT_GT(p.pool.held_slot_bytes(), 0u);
  EXPECT_LT(p.pool.held_slot_bytes(), std::uint64_t{whole_->node_count()} * 4);
}

TEST_F(NodePool, AListLargerThanTheBudgetIsDrawnCoarserNeverPastIt) {
  const std::vector<NodeId> ids = level(whole_->level_count() - 2);
  // The least pool: the root's page and one more.
  GpuPoolOptions o{0, 64u << 20};
  for (o.memory_bytes = 64 << 10;; o.memory_bytes += 64 << 10) {
    try {
      (void)GpuNodePool::blocks(*paged_, o);
      break;
    } catch (const InputError&) {
    }
  }
  Pooled p(*paged_, o);
  for (int f = 0; f < 5; ++f) {
    const Image got = p.frame(paged_->hierarchy(), camera_, f == 0 ? &ids : nullptr);
    const GpuPoolStats s = p.pool.stats();
    EXPECT_LE(s.resident_bytes, o.memory_bytes);
    EXPECT_GT(s.waiting_pages, 0u);
    EXPECT_GT(s.stand_ins, 0u);
    EXPECT_GT(drawn(got), 0u);
  }
}

TEST_F(NodePool, ABudgetBelowTwoPagesIsRefusedInOneLine) {
  try {
    (void)GpuNodePool::blocks(*paged_, {16 << 10, 1 << 20, 16 << 10});
    FAIL() << "a pool of 16 KiB accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--gpu-memory: 0.0 MiB is below"), std::string::npos)
        << e.what();
  }
}

}  // namespace treecut::splat
