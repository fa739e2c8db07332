// Renderer benchmarks on OSMesa (llvmpipe), 1280x720, fast splats:
//
//  - FeedbackOverhead/{0,1,2}: frame time (poll + upload + draw + glFinish)
//    of the dragon with the same cut size, without the Feedback Stage (0),
//    with its thread iterating beside the render thread (1: the camera turns
//    a little every frame, so the stage never idles), and with its thread
//    running under a static camera after convergence (2). Target: <= 3 %.
//  - FullVsLod/{dragon,lion}/{full,lod}: frame time of the full-detail cut and
//    of the smallest optimization-strategy cut (budgets from 1/64 of the
//    leaves up, doubling) whose image has PSNR >= 30 dB against full detail
//    from the same view. Target: LOD frame <= 40 % of full.
//
// Each needs ../shared/assets; a missing model skips its benchmarks with a
// message. Run: build/gl/tests/bench/render_bench --benchmark_min_time=2
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>

#include "test_support.hpp"
#include "treecut/controller.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/registry.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/strategies/builtin.hpp"

namespace {

using namespace treecut;
using namespace treecut::splat;

constexpr int kWidth = 1280;
constexpr int kHeight = 720;
const glm::ivec2 kSize(kWidth, kHeight);

GlContext& context() {
  static OsmesaContext ctx(kWidth, kHeight);
  return ctx;
}

const Hierarchy* model(const std::string& asset) {
  static std::map<std::string, std::unique_ptr<Hierarchy>> cache;
  auto it = cache.find(asset);
  if (it != cache.end()) return it->second.get();
  std::unique_ptr<Hierarchy> h;
  if (const auto path = test::shared_asset(asset)) {
    h = std::make_unique<Hierarchy>(open_model(*path).hierarchy);
  }
  return cache.emplace(asset, std::move(h)).first->second.get();
}

ViewSnapshot snapshot(const Camera& c, glm::vec3 light) {
  ViewSnapshot v;
  v.view = c.view_matrix();
  v.projection = c.projection_matrix(float(kWidth) / float(kHeight));
  v.viewport = kSize;
  v.light_dir = light;
  v.finalize();
  return v;
}

std::unique_ptr<Strategy> optimization(std::size_t budget) {
  StrategyRegistry registry;
  strategies::register_builtin(registry);
  auto s = registry.create("optimization");
  s->set_param("max_nodes", double(budget));
  return s;
}

// The converged optimization cut of `budget` nodes for camera `c` (synchronous stage).
std::vector<NodeId> converged_cut(const Hierarchy& h, const Camera& c, std::size_t budget) {
  StageOptions o;
  o.launch = Launch::Manual;
  Controller ctl(make_model(h), optimization(budget), snapshot(c, {0, 0, 1}), o);
  ctl.set_camera(c.view_matrix(), c.projection_matrix(float(kWidth) / float(kHeight)), kSize);
  for (int i = 0; i < 2000; ++i) {
    ctl.begin_frame();
    if (ctl.stage().counters().converged && ctl.stage().counters().iterations > 0) break;
    ctl.stage().step();
  }
  const FrameLists lists = ctl.begin_frame();
  return {lists.current.nodes.begin(), lists.current.nodes.end()};
}

Image grab(const Renderer& r) {
  return Image{kWidth, kHeight, r.read_pixels()};
}

void FeedbackOverhead(benchmark::State& state) {
  const Hierarchy* h = model("dragon_vrip.ply");
  if (h == nullptr) {
    state.SkipWithError("../shared/assets/dragon_vrip.ply is absent");
    return;
  }
  context();
  Renderer renderer(*h, kSize);
  const RenderSettings settings;
  const std::size_t budget = h->leaf_count() / 4;
  const bool with_stage = state.range(0) != 0;
  const bool moving = state.range(0) == 1;
  Camera cam = default_camera(h->bounds_min(), h->bounds_max(), float(kWidth) / float(kHeight));
  const glm::vec3 center = cam.target;
  CutBuffer cut;
  std::unique_ptr<Controller> ctl;
  if (with_stage) {
    ctl = std::make_unique<Controller>(make_model(*h), optimization(budget),
                                       snapshot(cam, {0, 0, 1}));
  } else {
    const std::vector<NodeId> nodes = converged_cut(*h, cam, budget);
    cut.upload(*h, nodes);
  }
  std::uint64_t uploaded = 0;
  float angle = 0.0f;
  auto frame = [&] {
    if (!with_stage) {
      renderer.draw(cut, cam, settings, true);
      return;
    }
    // Arg 1: a small turn per frame keeps the stage iterating. Arg 2: a static
    // camera; the stage thread runs but has converged.
    if (moving) angle += 0.002f;
    const glm::vec3 off = cam.eye - center;
    Camera c = cam;
    c.eye = center + glm::vec3(off.x * std::cos(angle) - off.z * std::sin(angle), off.y,
                               off.x * std::sin(angle) + off.z * std::cos(angle));
    ctl->set_camera(c.view_matrix(), c.projection_matrix(float(kWidth) / float(kHeight)), kSize);
    const FrameLists lists = ctl->begin_frame();
    if (lists.current.generation != uploaded) {
      cut.upload(*lists.current.hierarchy, lists.current.nodes);
      uploaded = lists.current.generation;
    }
    renderer.draw(cut, c, settings, true);
  };
  // Untimed: grow the stage's cut to the budget first (same cut size as without).
  for (int i = 0; with_stage && i < 2000 && cut.size() < budget * 98 / 100; ++i) frame();
  std::size_t cut_sum = 0, frames = 0;
  for (auto _ : state) {
    frame();
    cut_sum += cut.size();
    ++frames;
  }
  state.counters["cut_size"] = double(cut_sum) / double(std::max<std::size_t>(frames, 1));
  if (with_stage) {
    state.counters["iterations"] = double(ctl->stage().counters().iterations);
    state.counters["exchanges"] = double(ctl->stage().counters().exchanges);
  }
}
BENCHMARK(FeedbackOverhead)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

struct LodChoice {
  std::vector<NodeId> nodes;
  double psnr_db = 0.0;
};

// The smallest budget (doubling from leaves/64) whose converged cut reaches 30 dB.
const LodChoice& lod_choice(const std::string& asset, const Hierarchy& h, Renderer& renderer,
                            const Camera& cam) {
  static std::map<std::string, LodChoice> chosen;
  if (auto it = chosen.find(asset); it != chosen.end()) return it->second;
  const RenderSettings settings;
  CutBuffer full;
  full.upload(h, TreeCut::leaf_cut(h).nodes());
  renderer.draw(full, cam, settings, true);
  const Image reference = grab(renderer);
  LodChoice best;
  for (std::size_t budget = std::max<std::size_t>(h.leaf_count() / 64, 1);; budget *= 2) {
    best.nodes = converged_cut(h, cam, std::min<std::size_t>(budget, h.leaf_count()));
    CutBuffer lod;
    lod.upload(h, best.nodes);
    renderer.draw(lod, cam, settings, true);
    best.psnr_db = psnr(reference, grab(renderer));
    if (best.psnr_db >= 30.0 || budget >= h.leaf_count()) break;
  }
  return chosen.emplace(asset, std::move(best)).first->second;
}

// The lion scan is z-up, the dragon y-up.
glm::vec3 up_of(const std::string& asset) {
  return asset.rfind("lion", 0) == 0 ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
}

void FullVsLod(benchmark::State& state, const std::string& asset, bool lod) {
  const Hierarchy* h = model(asset);
  if (h == nullptr) {
    state.SkipWithError(("../shared/assets/" + asset + " is absent").c_str());
    return;
  }
  context();
  Renderer renderer(*h, kSize);
  const Camera cam = default_camera(h->bounds_min(), h->bounds_max(),
                                    float(kWidth) / float(kHeight), up_of(asset));
  CutBuffer cut;
  double psnr_db = std::numeric_limits<double>::infinity();
  if (lod) {
    const LodChoice& c = lod_choice(asset, *h, renderer, cam);
    cut.upload(*h, c.nodes);
    psnr_db = c.psnr_db;
  } else {
    cut.upload(*h, TreeCut::leaf_cut(*h).nodes());
  }
  const RenderSettings settings;
  for (auto _ : state) renderer.draw(cut, cam, settings, true);
  state.counters["cut_size"] = double(cut.size());
  state.counters["points"] = double(h->leaf_count());
  if (lod) state.counters["psnr_db"] = psnr_db;
}
BENCHMARK_CAPTURE(FullVsLod, dragon_full, std::string("dragon_vrip.ply"), false)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(FullVsLod, dragon_lod, std::string("dragon_vrip.ply"), true)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(FullVsLod, lion_full, std::string("lion_takanawa.ply"), false)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(FullVsLod, lion_lod, std::string("lion_takanawa.ply"), true)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
