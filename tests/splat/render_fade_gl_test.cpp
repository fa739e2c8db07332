// Fades of an exchange (StageOptions::blend_frames, CutBuffer::follow, the
// screen-door dither of the renderer) on OSMesa, with the Feedback Stage
// stepped by the test: an exchange from cut A to cut B under blend N shows N
// intermediate frames and then B; in each intermediate frame every pixel is
// A's or B's, a pixel once B's stays B's, and the share of B's pixels (among
// those where A and B differ) grows with every frame. Without blending the
// frame after the exchange is B.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 240;
constexpr int kHeight = 180;

// Rebuild strategy that hands back one fixed cut and converges.
class JumpStrategy final : public Strategy {
 public:
  explicit JumpStrategy(std::vector<NodeId> target) : Strategy({}), target_(std::move(target)) {}
  [[nodiscard]] std::string_view name() const override { return "jump"; }
  [[nodiscard]] Mode mode() const override { return Mode::Rebuild; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput&, IterationOutput& out) override {
    out.nodes->assign(target_.begin(), target_.end());
    out.result.converged = true;
  }

 private:
  std::vector<NodeId> target_;
};

bool same_pixel(const Image& a, const Image& b, std::size_t i) {
  return a.rgba[i] == b.rgba[i] && a.rgba[i + 1] == b.rgba[i + 1] && a.rgba[i + 2] == b.rgba[i + 2];
}

// Differs by more than 2/255 in a channel (hq's additive pass in another
// order rounds its half-float sums differently, by about one step).
bool far_pixel(const Image& a, const Image& b, std::size_t i) {
  for (std::size_t c = 0; c < 3; ++c) {
    if (std::abs(int(a.rgba[i + c]) - int(b.rgba[i + c])) > 2) return true;
  }
  return false;
}

class RenderFade : public ::testing::TestWithParam<SplatMode> {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  void SetUp() override {
    renderer_ = std::make_unique<Renderer>(*h_, glm::ivec2(kWidth, kHeight));
    camera_ = default_camera(h_->bounds_min(), h_->bounds_max(), float(kWidth) / kHeight);
    settings_.mode = GetParam();
    settings_.point_size_px = 4.0f;
    // A: one level; B: A with every other node refined (entering children,
    // leaving parents) in the same region.
    const int d = h_->level_count() - 4;
    a_.resize(h_->level_begin(d + 1) - h_->level_begin(d));
    std::iota(a_.begin(), a_.end(), h_->level_begin(d));
    TreeCut b = TreeCut::from_nodes(*h_, a_);
    for (std::size_t i = 0; i < a_.size(); i += 2) b.refine(*h_, a_[i]);
    b_.assign(b.nodes().begin(), b.nodes().end());
  }
  Image draw(const CutBuffer& cut) {
    renderer_->draw(cut, camera_, settings_, true);
    return Image{kWidth, kHeight, renderer_->read_pixels()};
  }
  // The frames from the first poll until the stage stops blending.
  std::vector<Image> run(unsigned blend, std::vector<bool>& exchanged) {
    StageOptions o;
    o.launch = Launch::Manual;
    o.blend_frames = blend;
    FeedbackStage stage(Model{h_, TreeCut::from_nodes(*h_, a_)}, std::make_unique<JumpStrategy>(b_),
                        o);
    CutBuffer cut;
    std::vector<Image> frames;
    for (int f = 0; f < 20; ++f) {
      const FrameLists lists = stage.poll();
      cut.follow(lists);
      frames.push_back(draw(cut));
      exchanged.push_back(lists.exchanged);
      stage.step();
    }
    return frames;
  }

  std::shared_ptr<const Hierarchy> h_ = std::make_shared<const Hierarchy>(
      build_from_points(tools::generate_model(tools::ModelKind::Terrain, 20000, 3)));
  std::vector<NodeId> a_, b_;
  std::unique_ptr<Renderer> renderer_;
  Camera camera_;
  RenderSettings settings_;
};

TEST_P(RenderFade, AnExchangeFadesOverNFramesBetweenTheOldAndTheNewImage) {
  constexpr unsigned kBlend = 4;
  // The two images in the fade's own draw order (weights 0 and 1), and as
  // one-call draws of A and B.
  CutBuffer fading;
  fading.upload(*h_, b_, a_);
  ASSERT_GT(fading.entering(), 0u);
  ASSERT_GT(fading.leaving(), 0u);
  fading.set_fade(0.0f);
  const Image old_image = draw(fading);
  fading.set_fade(1.0f);
  const Image new_image = draw(fading);
  CutBuffer plain;
  plain.upload(*h_, a_);
  const Image a_image = draw(plain);
  plain.upload(*h_, b_);
  const Image b_image = draw(plain);
  std::size_t differ = 0;
  std::size_t tie_a = 0;
  std::size_t tie_b = 0;
  for (std::size_t i = 0; i < old_image.rgba.size(); i += 4) {
    differ += !same_pixel(old_image, new_image, i);
    tie_a += far_pixel(old_image, a_image, i);
    tie_b += far_pixel(new_image, b_image, i);
  }
  ASSERT_GT(differ, old_image.rgba.size() / 4 / 50) << "A and B must look different";
  // The fade's order differs from the one-call order only at depth ties (and,
  // in hq, by the rounding of the additive pass).
  EXPECT_LE(tie_a, old_image.rgba.size() / 4 / 1000);
  EXPECT_LE(tie_b, old_image.rgba.size() / 4 / 1000);

  std::vector<bool> exchanged;
  const std::vector<Image> frames = run(kBlend, exchanged);
  std::size_t k = 0;
  while (k < exchanged.size() && !exchanged[k]) ++k;
  ASSERT_LT(k + kBlend, frames.size()) << "no exchange";
  for (std::size_t f = 0; f < k; ++f) EXPECT_EQ(frames[f].rgba, a_image.rgba) << f;
  std::vector<bool> is_new(old_image.rgba.size() / 4, false);
  double last_share = 0.0;
  for (std::size_t f = k; f < k + kBlend; ++f) {
    std::size_t neither = 0;
    std::size_t now_new = 0;
    std::size_t went_back = 0;
    for (std::size_t i = 0; i < old_image.rgba.size(); i += 4) {
      if (same_pixel(old_image, new_image, i)) {
        neither += !same_pixel(frames[f], old_image, i);
        continue;
      }
      const bool n = same_pixel(frames[f], new_image, i);
      neither += !n && !same_pixel(frames[f], old_image, i);
      went_back += is_new[i / 4] && !n;
      is_new[i / 4] = n;
      now_new += n;
    }
    const double share = double(now_new) / double(differ);
    std::printf("%s frame %zu after the exchange: %.3f of the %zu changing pixels are new\n",
                std::string(splat_mode_name(GetParam())).c_str(), f - k, share, differ);
    EXPECT_EQ(neither, 0u) << "frame " << f - k << ": pixels that are neither old nor new";
    EXPECT_EQ(went_back, 0u) << "frame " << f - k;
    EXPECT_GT(share, last_share) << "frame " << f - k;
    EXPECT_LT(share, 1.0) << "frame " << f - k;
    // The dither thresholds are uniform over 8x8 tiles: the share follows the weight.
    const double weight = double(f - k + 1) / double(kBlend + 1);
    EXPECT_NEAR(share, weight, 0.2) << "frame " << f - k;
    last_share = share;
  }
  for (std::size_t f = k + kBlend; f < frames.size(); ++f) {
    EXPECT_EQ(frames[f].rgba, new_image.rgba) << "frame " << f - k << " after the exchange";
  }
}

TEST_P(RenderFade, WithoutBlendingTheExchangeFrameIsTheNewImage) {
  CutBuffer plain;
  plain.upload(*h_, a_);
  const Image a_image = draw(plain);
  plain.upload(*h_, b_);
  const Image b_image = draw(plain);
  std::vector<bool> exchanged;
  const std::vector<Image> frames = run(0, exchanged);
  std::size_t k = 0;
  while (k < exchanged.size() && !exchanged[k]) ++k;
  ASSERT_LT(k, frames.size());
  for (std::size_t f = 0; f < k; ++f) EXPECT_EQ(frames[f].rgba, a_image.rgba);
  for (std::size_t f = k; f < frames.size(); ++f) EXPECT_EQ(frames[f].rgba, b_image.rgba);
}

INSTANTIATE_TEST_SUITE_P(Modes, RenderFade,
                         ::testing::Values(SplatMode::Fast, SplatMode::HighQuality,
                                           SplatMode::FixedSize),
                         [](const ::testing::TestParamInfo<SplatMode>& p) {
                           return std::string(splat_mode_name(p.param));
                         });

}  // namespace
}  // namespace treecut::splat

namespace treecut::splat {
namespace {

// The `exchanges` column (cumulative) of a stats.csv, one value per frame.
std::vector<long> exchanges_per_frame(const std::filesystem::path& csv) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::size_t column = 0;
  for (std::size_t pos = 0, i = 0;; ++i) {
    const std::size_t comma = line.find(',', pos);
    if (line.substr(pos, comma - pos) == "exchanges") {
      column = i;
      break;
    }
    if (comma == std::string::npos) return {};
    pos = comma + 1;
  }
  std::vector<long> v;
  while (std::getline(in, line)) {
    std::size_t pos = 0;
    for (std::size_t i = 0; i < column; ++i) pos = line.find(',', pos) + 1;
    v.push_back(std::stol(line.substr(pos)));
  }
  return v;
}

// `treecut render --blend N`: a fade runs to its end before the next exchange,
// so exchanges come at least N frames apart; without it the --sync stage
// exchanges every frame while the cut grows. Out of range: exit 2, one line.
TEST(RenderFadeCommand, BlendSpacesTheExchangesByItsFrames) {
  const std::filesystem::path dir = test::scratch_dir("render_fade_command");
  const std::string common =
      "render --default-points 30000 --sync --no-png --frames 30 --warmup 0 -p max_nodes=3000 ";
  for (const unsigned blend : {0u, 4u}) {
    const std::filesystem::path out = dir / ("blend" + std::to_string(blend));
    const test::CommandResult r =
        test::run_treecut(common + "--blend " + std::to_string(blend) + " -o " + test::quote(out));
    ASSERT_EQ(r.code, 0) << r.out;
    const std::vector<long> ex = exchanges_per_frame(out / "stats.csv");
    ASSERT_EQ(ex.size(), 30u) << r.out;
    std::size_t shortest = ex.size();
    std::size_t last = 0;
    bool seen = false;
    for (std::size_t f = 1; f < ex.size(); ++f) {
      EXPECT_LE(ex[f] - ex[f - 1], 1) << "frame " << f;
      if (ex[f] == ex[f - 1]) continue;
      if (seen) shortest = std::min(shortest, f - last);
      last = f;
      seen = true;
    }
    ASSERT_LT(shortest, ex.size()) << "fewer than two exchanges: " << r.out;
    if (blend == 0) {
      EXPECT_EQ(shortest, 1u);
    } else {
      EXPECT_GE(shortest, blend);
    }
  }
  const test::CommandResult bad =
      test::run_treecut(common + "--blend 65 -o " + test::quote(dir / "bad"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_EQ(std::count(bad.out.begin(), bad.out.end(), '\n'), 1) << bad.out;
  EXPECT_NE(bad.out.find("--blend"), std::string::npos) << bad.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad"));
}

}  // namespace
}  // namespace treecut::splat
