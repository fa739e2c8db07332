// Ordered and partial draws (Renderer::draw_ranges) on OSMesa. What holds:
//  - ranges that partition the cut, drawn in buffer order, give exactly the
//    one-call image in every mode;
//  - in any other order, hq gives exactly the one-call image (its depth is a
//    minimum and its additive pass runs in buffer order); fast and fixed may
//    differ only where two splats have exactly the same depth at a pixel (the
//    first drawn wins: splats of neighbouring nodes do tie, about 10 of 43,200
//    pixels here), which the test bounds at 0.1 % of the pixels;
//  - a subset of ranges draws exactly the image of a list of those nodes;
//  - the hook runs once after every range, in the given order, with depth
//    and color writes off.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <random>
#include <vector>

#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/gl.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 240;
constexpr int kHeight = 180;

// A cut that mixes levels: random refinements from the root down to `target` nodes.
std::vector<NodeId> mixed_cut(const Hierarchy& h, std::size_t target, unsigned seed) {
  TreeCut cut = TreeCut::root_cut(h);
  std::mt19937 rng(seed);
  for (int misses = 0; cut.size() < target && misses < 10000;) {
    const NodeId n = cut.nodes()[rng() % cut.size()];
    if (h.is_leaf(n)) {
      ++misses;
    } else {
      cut.refine(h, n);
    }
  }
  std::vector<NodeId> v(cut.nodes().begin(), cut.nodes().end());
  return v;
}

// `parts` ranges of random sizes that partition [0, n).
std::vector<CutRange> partition(std::size_t n, std::size_t parts, std::mt19937& rng) {
  std::vector<std::uint32_t> cuts{0, static_cast<std::uint32_t>(n)};
  for (std::size_t i = 1; i < parts; ++i) cuts.push_back(static_cast<std::uint32_t>(rng() % n));
  std::sort(cuts.begin(), cuts.end());
  std::vector<CutRange> r;
  for (std::size_t i = 0; i + 1 < cuts.size(); ++i) r.push_back({cuts[i], cuts[i + 1] - cuts[i]});
  return r;
}

std::size_t differing_pixels(const Image& a, const Image& b) {
  std::size_t d = 0;
  for (std::size_t i = 0; i < a.rgba.size(); i += 4) {
    d += a.rgba[i] != b.rgba[i] || a.rgba[i + 1] != b.rgba[i + 1] || a.rgba[i + 2] != b.rgba[i + 2];
  }
  return d;
}

class RenderRanges : public ::testing::TestWithParam<SplatMode> {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  void SetUp() override {
    renderer_ = std::make_unique<Renderer>(h_, glm::ivec2(kWidth, kHeight));
    camera_ = default_camera(h_.bounds_min(), h_.bounds_max(), float(kWidth) / kHeight);
    settings_.mode = GetParam();
    settings_.point_size_px = 4.0f;
  }
  Image whole(const CutBuffer& cut) {
    renderer_->draw(cut, camera_, settings_, true);
    return Image{kWidth, kHeight, renderer_->read_pixels()};
  }
  Image ranges(const CutBuffer& cut, std::span<const CutRange> r, RangeHook* hook = nullptr) {
    renderer_->draw_ranges(cut, r, camera_, settings_, hook, true);
    return Image{kWidth, kHeight, renderer_->read_pixels()};
  }

  Hierarchy h_ = build_from_points(tools::generate_model(tools::ModelKind::City, 30000, 5));
  std::unique_ptr<Renderer> renderer_;
  Camera camera_;
  RenderSettings settings_;
};

TEST_P(RenderRanges, APartitionInBufferOrderIsTheOneCallImage) {
  const std::vector<NodeId> nodes = mixed_cut(h_, 6000, 1);
  CutBuffer cut;
  cut.upload(h_, nodes);
  const Image one = whole(cut);
  std::mt19937 rng(2);
  for (const std::size_t parts : {1, 7, 300}) {
    const std::vector<CutRange> r = partition(cut.size(), parts, rng);
    EXPECT_EQ(differing_pixels(ranges(cut, r), one), 0u) << parts << " ranges";
  }
}

TEST_P(RenderRanges, AnyOrderEqualsTheOneCallImageExceptAtDepthTies) {
  const std::vector<NodeId> nodes = mixed_cut(h_, 6000, 3);
  CutBuffer cut;
  cut.upload(h_, nodes);
  const Image one = whole(cut);
  std::mt19937 rng(4);
  const std::size_t pixels = one.rgba.size() / 4;
  for (const std::size_t parts : {2, 50, 1000}) {
    std::vector<CutRange> r = partition(cut.size(), parts, rng);
    std::reverse(r.begin(), r.end());
    const std::size_t reversed = differing_pixels(ranges(cut, r), one);
    std::shuffle(r.begin(), r.end(), rng);
    const std::size_t shuffled = differing_pixels(ranges(cut, r), one);
    if (GetParam() == SplatMode::HighQuality) {
      EXPECT_EQ(reversed, 0u) << parts;
      EXPECT_EQ(shuffled, 0u) << parts;
    } else {
      // Ties of exactly equal 24-bit depth between different splats: rare
      // (under 0.4 % of the pixels with the city filling the frame, as the
      // first view fits the box since issue 43; under 0.1 % at the distance
      // of its bounding sphere).
      EXPECT_LE(reversed, pixels / 250) << parts;
      EXPECT_LE(shuffled, pixels / 250) << parts;
    }
    std::printf("%s, %zu ranges: %zu (reversed) and %zu (shuffled) of %zu pixels differ\n",
                std::string(splat_mode_name(GetParam())).c_str(), parts, reversed, shuffled,
                pixels);
  }
}

TEST_P(RenderRanges, ASubsetOfRangesDrawsExactlyThoseNodes) {
  const std::vector<NodeId> nodes = mixed_cut(h_, 6000, 6);
  CutBuffer cut;
  cut.upload(h_, nodes);
  std::mt19937 rng(7);
  const std::vector<CutRange> all = partition(cut.size(), 40, rng);
  std::vector<CutRange> some;
  std::vector<NodeId> subset;
  for (std::size_t i = 0; i < all.size(); i += 3) {
    some.push_back(all[i]);
    const auto ids = cut.ids().subspan(all[i].first, all[i].count);
    subset.insert(subset.end(), ids.begin(), ids.end());
  }
  CutBuffer only;
  only.upload(h_, subset);
  const FrameStats stats = renderer_->draw_ranges(cut, some, camera_, settings_, nullptr, true);
  EXPECT_EQ(stats.splats, subset.size());
  const Image partial{kWidth, kHeight, renderer_->read_pixels()};
  EXPECT_EQ(differing_pixels(partial, whole(only)), 0u);
  EXPECT_GT(differing_pixels(partial, whole(cut)), 0u);  // the rest was left out
}

// Records the calls and the GL state it is called in.
class RecordingHook final : public RangeHook {
 public:
  void after_range(std::size_t index, const ViewSnapshot& view) override {
    calls.push_back(index);
    GLint depth_writes = 1;
    GLint color[4] = {1, 1, 1, 1};
    gl::GetIntegerv(GL_DEPTH_WRITEMASK, &depth_writes);
    gl::GetIntegerv(GL_COLOR_WRITEMASK, color);
    writes_off = writes_off && depth_writes == 0 && color[0] == 0 && color[3] == 0;
    size_ok = size_ok && view.viewport == glm::ivec2(kWidth, kHeight);
    // A hook may bind its own program and vertex array (the renderer rebinds).
    gl::UseProgram(0);
    gl::BindVertexArray(0);
  }
  std::vector<std::size_t> calls;
  bool writes_off = true;
  bool size_ok = true;
};

TEST_P(RenderRanges, TheHookRunsAfterEveryRangeWithWritesOff) {
  const std::vector<NodeId> nodes = mixed_cut(h_, 3000, 8);
  CutBuffer cut;
  cut.upload(h_, nodes);
  const Image one = whole(cut);
  std::mt19937 rng(9);
  std::vector<CutRange> r = partition(cut.size(), 25, rng);
  r.push_back({0, 0});  // an empty range gets its call too
  r.push_back({static_cast<std::uint32_t>(cut.size()) + 5, 10});  // past the end: clipped
  RecordingHook hook;
  const Image drawn = ranges(cut, r, &hook);
  std::vector<std::size_t> expected(r.size());
  std::iota(expected.begin(), expected.end(), std::size_t{0});
  EXPECT_EQ(hook.calls, expected);
  EXPECT_TRUE(hook.writes_off);
  EXPECT_TRUE(hook.size_ok);
  EXPECT_EQ(differing_pixels(drawn, one), 0u);
}

INSTANTIATE_TEST_SUITE_P(Modes, RenderRanges,
                         ::testing::Values(SplatMode::Fast, SplatMode::HighQuality,
                                           SplatMode::FixedSize),
                         [](const ::testing::TestParamInfo<SplatMode>& p) {
                           return std::string(splat_mode_name(p.param));
                         });

}  // namespace
}  // namespace treecut::splat
