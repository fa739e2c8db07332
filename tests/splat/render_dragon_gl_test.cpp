// Headless GL test on a real scan: the full-detail dragon differs from its
// root-only cut (skipped when ../shared/assets is absent).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/model_io.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"
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

// The paged cache (issue 44) quantizes positions and radii per page: the
// dragon, the lion and a city drawn from their caches are the frames of the
// hierarchies built in memory, but for pixels where overlapping splats
// trade places. How many such pixels a model has is measured, not assumed:
// the same build seen from an eye moved by the quantization's own bound
// (extent / 65534) changes that many, and at full detail the cache may
// change no more than half again as many (0.2 % where there are fewer):
// measured, dragon 0.016 % (the moved eye 0.061 %), lion 0.010 % (0.020 %),
// city 1.41 % (1.43 %: its flat walls and roofs are coplanar splats that
// any move reorders). A coarse cut's interior splats also grow or shrink a
// little at their edges (radii rounded up, drawn radii in 8 bits): under
// 0.3 % of the pixels (0.08, 0.05 and 0.21 %).
TEST(SplatDragon, ModelsFromThePagedCacheDrawTheirBuildsFrames) {
  context();
  const std::filesystem::path dir = test::scratch_dir("splat_paged");
  std::vector<std::pair<std::string, PointSet>> models;
  for (const char* name : {"dragon_vrip.ply", "lion_takanawa.ply"}) {
    const auto shared = test::shared_dir();
    if (!shared || !std::filesystem::exists(*shared / "assets" / name)) continue;
    models.emplace_back(name, load_point_file(*shared / "assets" / name));
  }
  models.emplace_back("city", tools::generate_model(tools::ModelKind::City, 200000, 3));
  for (auto& [name, points] : models) {
    SCOPED_TRACE(name);
    const Hierarchy built = build_from_points(std::move(points));
    save_cache(built, {}, dir / "m.tch");
    std::string why;
    const std::optional<Hierarchy> paged = load_cache(dir / "m.tch", std::nullopt, &why);
    ASSERT_TRUE(paged) << why;
    const Camera cam =
        default_camera(built.bounds_min(), built.bounds_max(), float(kWidth) / kHeight);
    const glm::vec3 extent = built.bounds_max() - built.bounds_min();
    Camera moved = cam;
    moved.eye += glm::vec3(std::max({extent.x, extent.y, extent.z}) / 65534.0f);
    const int coarse = std::max(1, built.level_count() - 5);
    for (const bool full : {true, false}) {
      SCOPED_TRACE(full ? "full detail" : "coarse cut");
      auto frame = [&](const Hierarchy& h, const Camera& c) {
        Renderer renderer(h, {kWidth, kHeight});
        CutBuffer cut;
        std::vector<NodeId> level;  // the nodes of depth COARSE, and the leaves above it
        for (NodeId n = 0; n < h.level_begin(coarse + 1); ++n)
          if (h.arrays().depth[n] == coarse || h.is_leaf(n)) level.push_back(n);
        cut.upload(h, full ? TreeCut::leaf_cut(h).nodes() : TreeCut::from_nodes(h, level).nodes());
        renderer.draw(cut, c, RenderSettings{}, true);
        return Image{kWidth, kHeight, renderer.read_pixels()};
      };
      const Image a = frame(built, cam), b = frame(*paged, cam), control = frame(built, moved);
      const double reordered = changed_fraction(a, control);
      if (full) {
        EXPECT_LE(changed_fraction(a, b), std::max(0.002, 1.5 * reordered)) << reordered;
      } else {  // interior splats also grow or shrink a little at their edges
        EXPECT_LT(changed_fraction(a, b), 0.003);
      }
    }
  }
}

}  // namespace
}  // namespace treecut::splat
