// Headless GL test on a real scan: the full-detail dragon differs from its
// root-only cut (skipped when ../shared/assets is absent).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "test_support.hpp"
#include "treecut/model_io.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 320;
constexpr int kHeight = 240;

GlContext& context() {
  static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
  ctx->make_current();
  return *ctx;
}

std::array<std::uint8_t, 3> background_bytes(const RenderSettings& s) {
  auto to_byte = [](float v) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
  };
  return {to_byte(s.background.x), to_byte(s.background.y), to_byte(s.background.z)};
}

// The full-detail dragon and its root-only cut render different images.
TEST(SplatDragon, FullDetailDiffersFromRootOnly) {
  TREECUT_REQUIRE_ASSET(dragon, "dragon_vrip.ply");
  context();
  OpenOptions options;
  options.cache_path = test::scratch_dir("splat_dragon") / "dragon.tch";
  const Hierarchy h = open_model(dragon, options).hierarchy;
  Renderer renderer(h, {kWidth, kHeight});
  const Camera cam = default_camera(h.bounds_min(), h.bounds_max(), float(kWidth) / kHeight);
  CutBuffer full;
  full.upload(h, TreeCut::leaf_cut(h).nodes());
  CutBuffer root;
  root.upload(h, TreeCut::root_cut(h).nodes());
  RenderSettings s;
  renderer.draw(full, cam, s, true);
  const Image a{kWidth, kHeight, renderer.read_pixels()};
  renderer.draw(root, cam, s, true);
  const Image b{kWidth, kHeight, renderer.read_pixels()};
  const auto bg = background_bytes(s);
  EXPECT_GT(coverage(a, bg.data()).pixels, std::size_t(kWidth * kHeight) / 20);
  EXPECT_LT(psnr(a, b), 25.0);
  write_png(test::scratch_dir("splat_dragon_png") / "dragon_full.png", a);
}

}  // namespace
}  // namespace treecut::splat
