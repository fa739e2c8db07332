// The in-frame HLOD traversal (strategies/hlod_traversal.hpp) on the GL
// occlusion device (splat/occlusion_device_gl.hpp), OSMesa, a small
// generated city and its walkthrough:
//  - Coh(B) reads GL_QUERY_RESULT only after GL_QUERY_RESULT_AVAILABLE said
//    true for that query, or in a read the device counts as a wait, and
//    never such a wait while its traversal queue has blocks (the interposer
//    of tests/culling/chc_gl_test.cpp, with availability hidden for a while to make
//    the check live);
//  - Coh(B)'s image against Bool's (the paper's reference) along the walk:
//    PSNR >= 30 dB on average (section 5.2 of the paper);
//  - `treecut bench occlusion` prints the HLOD table and the PSNR lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "query_check.hpp"
#include "test_support.hpp"
#include "treecut/attributes.hpp"
#include "treecut/culling/hlod_traversal.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/gl.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/occlusion_device_gl.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::splat {
namespace {

using culling::HlodBlocks;
using culling::HlodFrameStats;
using culling::HlodMode;
using culling::HlodOptions;
using culling::HlodTraversal;

constexpr int kWidth = 320;
constexpr int kHeight = 180;

std::shared_ptr<const Hierarchy> city() {
  static std::shared_ptr<const Hierarchy> h;
  if (!h) {
    PointSet ps = tools::generate_city(40000, 5);
    complete_attributes(ps);
    h = std::make_shared<const Hierarchy>(build_hierarchy(std::move(ps)));
  }
  return h;
}

// `count` cameras along the walkthrough, interpolated between its keys (a
// coherent walk: each frame near the last).
std::vector<Camera> walk(const Hierarchy& h, int count) {
  const auto keys = tools::scene_walkthrough(tools::ModelKind::City);
  const glm::vec3 center = 0.5f * (h.bounds_min() + h.bounds_max());
  const float radius = 0.5f * glm::length(h.bounds_max() - h.bounds_min());
  std::vector<Camera> out;
  for (int i = 0; i < count; ++i) {
    const float u = float(keys.size() - 1) * float(i) / float(count - 1);
    const std::size_t k = std::min<std::size_t>(std::size_t(u), keys.size() - 2);
    const float f = u - float(k);
    Camera c;
    c.eye = glm::mix(keys[k].eye, keys[k + 1].eye, f);
    c.target = glm::mix(keys[k].target, keys[k + 1].target, f);
    c.up = keys[k].up;
    c.fov_y_deg = keys[k].fov_deg;
    fit_clip_planes(c, center, radius);
    out.push_back(c);
  }
  return out;
}

ViewSnapshot view_of(const Camera& c) { return c.view({kWidth, kHeight}); }

using test::QueryCheck;  // tests/support/query_check.hpp

class HlodGl : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  void SetUp() override {
    h_ = city();
    blocks_ = HlodBlocks::build(*h_, 300);
    renderer_ = std::make_unique<Renderer>(*h_, glm::ivec2(kWidth, kHeight));
    device_ = std::make_unique<GlOcclusionDevice>(*renderer_, blocks_);
  }
  HlodFrameStats frame(HlodTraversal& t, const Camera& c) {
    device_->set_view_render_thread(c, settings_);
    return t.frame_render_thread(*device_, view_of(c), true);
  }
  Image grab() const { return Image{kWidth, kHeight, renderer_->read_pixels()}; }

  std::shared_ptr<const Hierarchy> h_;
  HlodBlocks blocks_;
  std::unique_ptr<Renderer> renderer_;
  std::unique_ptr<GlOcclusionDevice> device_;
  RenderSettings settings_;
};

TEST_F(HlodGl, CohBNeverReadsAResultBeforeItIsAvailableWhileItHasWork) {
  const auto cameras = walk(*h_, 16);
  HlodTraversal t(*h_, blocks_, {HlodMode::CohB});
  for (const Camera& c : cameras) frame(t, c);  // the pool grows to what the walk needs
  t.reset();
  const QueryCheck check;
  QueryCheck::has_work = [&t] { return t.queued() > 0; };
  std::uint64_t blocking = 0, queries = 0, delayed = 0;
  for (const Camera& c : cameras) {
    const HlodFrameStats s = frame(t, c);
    blocking += s.blocking_reads;
    queries += s.queries;
    delayed += s.delayed;
  }
  EXPECT_GT(queries, 0u);
  EXPECT_GT(delayed, 0u);
  EXPECT_EQ(static_cast<std::uint64_t>(QueryCheck::reads), queries);
  EXPECT_EQ(static_cast<std::uint64_t>(QueryCheck::early_reads), blocking);
  EXPECT_EQ(QueryCheck::early_with_work, 0);
  EXPECT_GT(QueryCheck::hidden, 0) << "the check hid available results";
  EXPECT_LT(blocking, queries);
}

TEST_F(HlodGl, CohBImageIsWithin30DbOfBoolAlongTheWalk) {
  const auto cameras = walk(*h_, 24);
  HlodTraversal ref(*h_, blocks_, {HlodMode::Bool});
  HlodTraversal coh(*h_, blocks_, {HlodMode::CohB});
  HlodTraversal sw(*h_, blocks_, {HlodMode::SwB});
  double sum = 0.0;
  int differing = 0;
  std::uint64_t dn_coh = 0, dn_bool = 0, dn_sw = 0;
  for (const Camera& c : cameras) {
    dn_bool += frame(ref, c).drawn;
    const Image a = grab();
    dn_coh += frame(coh, c).drawn;
    const Image b = grab();
    dn_sw += frame(sw, c).drawn;
    const double p = std::min(psnr(a, b), 99.0);  // identical frames: capped as --psnr does
    sum += p;
    differing += p < 99.0 ? 1 : 0;
  }
  const double mean = sum / double(cameras.size());
  RecordProperty("psnr_mean_db", std::to_string(mean));
  RecordProperty("dn", std::to_string(dn_bool) + " Bool, " + std::to_string(dn_sw) + " SW(B), " +
                           std::to_string(dn_coh) + " Coh(B)");
  EXPECT_GE(mean, 30.0) << differing << " frames differ";
  // The VMSSE saves nodes on this walk, and Coh(B) stays near the ideal count.
  EXPECT_LT(dn_sw, dn_bool);
  EXPECT_LE(double(dn_coh), 1.25 * double(dn_sw)) << "Coh(B) " << dn_coh << " SW(B) " << dn_sw;
}

TEST(BenchOcclusionHlod, PrintsTheHlodTableAndThePsnrAndWritesTheCsv) {
  const auto dir = test::scratch_dir("bench_occlusion_hlod");
  const auto model = dir / "city.ply";
  ASSERT_EQ(test::run_treecut("gen city -n 20000 -o " + test::quote(model)).code, 0);
  const std::string walk_file =
      test::quote(std::filesystem::path(TREECUT_SOURCE_DIR) / "assets/paths/city_walk.campath");
  const std::string args = "bench occlusion " + test::quote(model) + " --path " + walk_file +
                           " --frames 4 --psnr-frames 3 --width 160 --height 90 --block-size "
                           "200 --csv " +
                           test::quote(dir / "csv");
  const auto r = test::run_treecut(args);
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* row : {"| Bool |", "| SW(B) |", "| Simp(B) |", "| Coh(B) |", "| hoq (stage"}) {
    EXPECT_NE(r.out.find(row), std::string::npos) << row << "\n" << r.out;
  }
  EXPECT_NE(r.out.find("PSNR (luma) of Coh(B) against Bool on 3 frames"), std::string::npos);
  const auto csv = dir / "csv" / "occlusion_city.csv";
  ASSERT_TRUE(std::filesystem::is_regular_file(csv));
  // Its own CSV is replaced by a second run; a file of the user's is not.
  EXPECT_EQ(test::run_treecut(args).code, 0);
  { std::ofstream(csv) << "mine\n"; }
  const auto refused = test::run_treecut(args);
  EXPECT_EQ(refused.code, 2) << refused.out;
  EXPECT_NE(refused.out.find(csv.string() + ": exists and is not a bench occlusion CSV"),
            std::string::npos)
      << refused.out;
  std::ifstream in(csv);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, "mine");
}

}  // namespace
}  // namespace treecut::splat
