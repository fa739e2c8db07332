// CutBuffer on OSMesa: the list is drawn in id order whatever order it comes
// in (same points, same image), and after repeated uploads (two GL buffers
// used in turn) the latest list is the one drawn.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 200;
constexpr int kHeight = 150;

class RenderCutBuffer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  void SetUp() override {
    renderer_ = std::make_unique<Renderer>(h_, glm::ivec2(kWidth, kHeight));
    camera_ = default_camera(h_.bounds_min(), h_.bounds_max(), float(kWidth) / kHeight);
  }
  Image render(const CutBuffer& cut) {
    renderer_->draw(cut, camera_, RenderSettings{}, true);
    return Image{kWidth, kHeight, renderer_->read_pixels()};
  }
  // The nodes of one level above the leaves: a coarse list of many splats.
  std::vector<NodeId> coarse_level() const {
    const int d = h_.level_count() - 2;
    std::vector<NodeId> v(h_.level_begin(d + 1) - h_.level_begin(d));
    std::iota(v.begin(), v.end(), h_.level_begin(d));
    return v;
  }
  std::uint64_t points_of(const std::vector<NodeId>& nodes) const {
    std::uint64_t p = 0;
    for (const NodeId n : nodes) p += h_.arrays().point_count[n];
    return p;
  }

  Hierarchy h_ = build_from_points(tools::generate_model(tools::ModelKind::Terrain, 20000, 3));
  std::unique_ptr<Renderer> renderer_;
  Camera camera_;
};

}  // namespace

TEST_F(RenderCutBuffer, AnyInputOrderDrawsTheSameSplatsAndImage) {
  const std::vector<NodeId> sorted = coarse_level();
  ASSERT_GT(sorted.size(), 100u);
  std::vector<NodeId> shuffled = sorted;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(42));
  ASSERT_FALSE(std::is_sorted(shuffled.begin(), shuffled.end()));

  CutBuffer a, b;
  a.upload(h_, sorted);
  b.upload(h_, shuffled);
  EXPECT_EQ(a.size(), sorted.size());
  EXPECT_EQ(b.size(), sorted.size());
  EXPECT_EQ(a.points(), points_of(sorted));
  EXPECT_EQ(b.points(), points_of(sorted));
  const Image ia = render(a);
  const Image ib = render(b);
  const std::uint8_t background[3] = {28, 31, 36};  // RenderSettings' default, in sRGB bytes
  EXPECT_GT(double(coverage(ia, background).pixels), 0.05 * kWidth * kHeight);
  EXPECT_EQ(changed_fraction(ia, ib, 0), 0.0);
}

TEST_F(RenderCutBuffer, TheLatestUploadIsDrawn) {
  const std::vector<NodeId> coarse = coarse_level();
  const TreeCut leaf_cut = TreeCut::leaf_cut(h_);
  const std::vector<NodeId> leaves(leaf_cut.nodes().begin(), leaf_cut.nodes().end());
  CutBuffer fresh_coarse, fresh_leaves;
  fresh_coarse.upload(h_, coarse);
  fresh_leaves.upload(h_, leaves);
  const Image want_coarse = render(fresh_coarse);
  const Image want_leaves = render(fresh_leaves);
  ASSERT_GT(changed_fraction(want_coarse, want_leaves, 0), 0.0);

  CutBuffer cut;
  for (int round = 0; round < 3; ++round) {
    cut.upload(h_, leaves);
    EXPECT_EQ(changed_fraction(render(cut), want_leaves, 0), 0.0) << round;
    EXPECT_EQ(cut.size(), leaves.size());
    cut.upload(h_, coarse);
    EXPECT_EQ(changed_fraction(render(cut), want_coarse, 0), 0.0) << round;
    EXPECT_EQ(cut.size(), coarse.size());
    EXPECT_EQ(cut.points(), points_of(coarse));
  }
}

}  // namespace treecut::splat
