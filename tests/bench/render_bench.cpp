// Renderer benchmarks on OSMesa (llvmpipe), 1280x720, fast splats. Both
// compare two conditions frame by frame inside one benchmark (interleaved), so
// a load change on the machine hits both sides alike and the ratio is
// measured in the same run. Wall times are medians over all frames;
// *_cpu_ms is the mean CPU time of the whole process per frame (render
// thread, llvmpipe's rasterizer threads, the stage thread), which hardly
// depends on what else the machine runs; *_render_thread_ms that of the
// render thread alone (GL calls, vertex and geometry stages, binning, and
// with the stage: poll, sort and upload).
//
//  - FeedbackOverhead/{static,moving}: frame time (poll + sort/upload after an
//    exchange + draw + glFinish) of the dragon at the same cut size (budget a
//    quarter of the leaves) with and without the Feedback Stage. Blocks of 16
//    frames alternate: "off" draws the stage's latest list, frozen, and leaves
//    the stage alone (its thread sleeps: the block starts only once no
//    iteration runs), "on" drives the Controller and draws its lists. static: the camera stands
//    still (the stage has converged and must not iterate); moving: the camera
//    swings about the model every frame in both blocks, so the stage iterates
//    all the time. overhead_pct is the median over neighbouring off/on block
//    pairs of (on median / off median - 1). The stage thread runs at
//    StagePriority::Idle, as in `treecut render` and `treecut view` (raised
//    to normal priority while a request waits past StageOptions::
//    starvation_bound); the moving case is also measured never raised
//    (bound 0), at Low and at Normal. Target: overhead_pct <= 3.
//  - FullVsLod/{dragon,lion}: the full-detail (leaf) cut against the smallest
//    optimization-strategy cut (default parameters) whose image has PSNR >= 30
//    dB against full detail from the same view. The budget is found by
//    doubling from 1/64 of the leaves, then bisection to 1/64 of the budget.
//    Full and LOD frames alternate. Target: ratio_pct (LOD / full, wall
//    medians) <= 40.
//
// Each needs ../shared/assets; a missing model skips its benchmarks with a
// message. Run: build/perf/tests/bench/render_bench --benchmark_min_time=20
#include <benchmark/benchmark.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "test_support.hpp"
#include "treecut/controller.hpp"
#include "treecut/file_io.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/registry.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/splat/scene_draw.hpp"
#include "treecut/strategies/builtin.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"

namespace {

using namespace treecut;
using namespace treecut::tools;
using namespace treecut::splat;

constexpr int kWidth = 1280;
constexpr int kHeight = 720;
const glm::ivec2 kSize(kWidth, kHeight);
constexpr float kAspect = float(kWidth) / float(kHeight);

GlContext& context() {
  static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
  return *ctx;
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

// The asset's hierarchy, or nullptr with the benchmark marked skipped (the
// shared assets are optional).
const Hierarchy* model_or_skip(benchmark::State& state, const std::string& asset) {
  const Hierarchy* h = model(asset);
  if (h == nullptr) state.SkipWithError(("../shared/assets/" + asset + " is absent").c_str());
  return h;
}

ViewSnapshot snapshot(const Camera& c, glm::vec3 light) {
  ViewSnapshot v;
  v.view = c.view_matrix();
  v.projection = c.projection_matrix(kAspect);
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
  ctl.set_camera(c.view_matrix(), c.projection_matrix(kAspect), kSize);
  for (int i = 0; i < 2000; ++i) {
    ctl.begin_frame();
    if (ctl.stage().counters().converged && ctl.stage().counters().iterations > 0) break;
    ctl.stage().step();
  }
  const FrameLists lists = ctl.begin_frame();
  return {lists.current.nodes.begin(), lists.current.nodes.end()};
}

double cpu_ms(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

// Wall and process-CPU time of frames of one condition.
struct FrameTimes {
  std::vector<double> wall_ms;
  double cpu_ms_sum = 0.0;     // whole process
  double thread_ms_sum = 0.0;  // the render thread alone

  template <typename F>
  double measure(F&& frame) {
    const double cpu0 = cpu_ms(CLOCK_PROCESS_CPUTIME_ID);
    const double thread0 = cpu_ms(CLOCK_THREAD_CPUTIME_ID);
    const auto t0 = std::chrono::steady_clock::now();
    frame();
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    cpu_ms_sum += cpu_ms(CLOCK_PROCESS_CPUTIME_ID) - cpu0;
    thread_ms_sum += cpu_ms(CLOCK_THREAD_CPUTIME_ID) - thread0;
    wall_ms.push_back(ms);
    return ms;
  }
  [[nodiscard]] double mean_thread() const {
    return wall_ms.empty() ? 0.0 : thread_ms_sum / double(wall_ms.size());
  }
  /// Median wall time of the frames [first, end).
  [[nodiscard]] double median(std::size_t first = 0) const {
    if (first >= wall_ms.size()) return 0.0;
    std::vector<double> v(wall_ms.begin() + static_cast<std::ptrdiff_t>(first), wall_ms.end());
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  }
  [[nodiscard]] double mean_cpu() const {
    return wall_ms.empty() ? 0.0 : cpu_ms_sum / double(wall_ms.size());
  }
};

Image grab(const Renderer& r) {
  return Image{kWidth, kHeight, r.read_pixels()};
}

void FeedbackOverhead(
    benchmark::State& state, bool moving, StagePriority priority,
    std::chrono::milliseconds starvation_bound = StageOptions{}.starvation_bound) {
  const Hierarchy* h = model_or_skip(state, "dragon_vrip.ply");
  if (h == nullptr) return;
  context();
  Renderer renderer(*h, kSize);
  const RenderSettings settings;
  const std::size_t budget = h->leaf_count() / 4;
  const Camera cam = default_camera(h->bounds_min(), h->bounds_max(), kAspect);
  const glm::vec3 center = cam.target;
  // The camera of frame i: still, or swinging +-0.2 rad about the vertical axis.
  auto camera_at = [&](std::size_t i) {
    if (!moving) return cam;
    const float angle = 0.2f * std::sin(0.02f * float(i));
    const glm::vec3 off = cam.eye - center;
    Camera c = cam;
    c.eye = center + glm::vec3(off.x * std::cos(angle) - off.z * std::sin(angle), off.y,
                               off.x * std::sin(angle) + off.z * std::cos(angle));
    return c;
  };

  CutBuffer frozen;  // "off": the stage's last list before the block, uploaded untimed
  StageOptions options;
  options.priority = priority;
  options.starvation_bound = starvation_bound;
  Controller ctl(make_model(*h), optimization(budget), view_snapshot(cam, kSize, settings.light),
                 options);
  // "on": the library's frame (poll, upload on an exchange, draw), as in treecut render.
  RenderThreadFrame frame(ctl, renderer);
  const CutBuffer& cut = frame.cut();
  std::size_t frame_index = 0;
  auto on_frame = [&](const Camera& c) { frame.run_render_thread(c, settings, true); };
  // Untimed: grow the stage's cut to the budget first (same cut size as off),
  // and for the static camera let the stage converge.
  for (int i = 0; i < 3000; ++i) {
    on_frame(camera_at(frame_index++));
    const bool full = cut.size() >= budget * 98 / 100;
    if (full && (moving || ctl.stage().counters().converged)) break;
  }

  constexpr int kBlock = 16;
  FrameTimes off, on;
  std::size_t off_cut = 0, on_cut = 0;
  const StageCounters start = ctl.stage().counters();
  std::vector<double> block_ratios;  // on/off of the medians of each pair of blocks
  for (auto _ : state) {
    // Off: wait (untimed) until the last requested iteration has finished, so
    // the stage thread sleeps through the whole block.
    while (ctl.stage().processing()) std::this_thread::sleep_for(std::chrono::microseconds(200));
    // The same nodes as the on frames draw, not only as many: which nodes a
    // view's cut holds (how many face the eye) changes the frame's cost.
    frozen.upload(*h, ctl.stage().front().nodes);
    double seconds = 0.0;
    const std::size_t off_first = off.wall_ms.size(), on_first = on.wall_ms.size();
    for (int i = 0; i < kBlock; ++i) {
      const Camera c = camera_at(frame_index++);
      seconds += off.measure([&] { renderer.draw(frozen, c, settings, true); }) * 1e-3;
      off_cut += frozen.size();
    }
    for (int i = 0; i < kBlock; ++i) {
      const Camera c = camera_at(frame_index++);
      seconds += on.measure([&] { on_frame(c); }) * 1e-3;
      on_cut += cut.size();
    }
    block_ratios.push_back(on.median(on_first) / off.median(off_first));
    state.SetIterationTime(seconds);
  }
  const StageCounters& end = ctl.stage().counters();
  const auto on_frames = double(std::max<std::size_t>(on.wall_ms.size(), 1));
  state.counters["off_ms"] = off.median();
  state.counters["on_ms"] = on.median();
  // Median over the pairs of neighbouring blocks: robust to the load drifting.
  std::nth_element(block_ratios.begin(),
                   block_ratios.begin() + static_cast<std::ptrdiff_t>(block_ratios.size() / 2),
                   block_ratios.end());
  state.counters["overhead_pct"] =
      block_ratios.empty() ? 0.0 : 100.0 * (block_ratios[block_ratios.size() / 2] - 1.0);
  state.counters["off_cpu_ms"] = off.mean_cpu();
  state.counters["on_cpu_ms"] = on.mean_cpu();
  state.counters["off_render_thread_ms"] = off.mean_thread();
  state.counters["on_render_thread_ms"] = on.mean_thread();
  state.counters["off_cut"] =
      double(off_cut) / double(std::max<std::size_t>(off.wall_ms.size(), 1));
  state.counters["on_cut"] = double(on_cut) / on_frames;
  state.counters["iterations_per_on_frame"] = double(end.iterations - start.iterations) / on_frames;
  state.counters["exchanges_per_on_frame"] = double(end.exchanges - start.exchanges) / on_frames;
  // The bounded wait: how often the stage was raised, the worst request wait.
  state.counters["raises"] = double(end.boosts - start.boosts);
  state.counters["worst_wait_ms"] = double(end.wait_ns_max) * 1e-6;
}
BENCHMARK_CAPTURE(FeedbackOverhead, static, false, StagePriority::Idle)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();
BENCHMARK_CAPTURE(FeedbackOverhead, moving, true, StagePriority::Idle)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();
// Idle as before the bounded wait: never raised, however long a request waits.
BENCHMARK_CAPTURE(FeedbackOverhead, moving_never_raised, true, StagePriority::Idle,
                  std::chrono::milliseconds(0))
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();
// The stage thread at nice +10 and at the render thread's priority.
BENCHMARK_CAPTURE(FeedbackOverhead, moving_low_priority, true, StagePriority::Low)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();
BENCHMARK_CAPTURE(FeedbackOverhead, moving_normal_priority, true, StagePriority::Normal)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

struct LodChoice {
  std::vector<NodeId> nodes;
  std::size_t budget = 0;
  double psnr_db = 0.0;
};

// The smallest budget whose converged cut reaches 30 dB: doubling from
// leaves/64 brackets it, bisection narrows the bracket to budget/64.
const LodChoice& lod_choice(const std::string& asset, const Hierarchy& h, Renderer& renderer,
                            const Camera& cam) {
  static std::map<std::string, LodChoice> chosen;
  if (auto it = chosen.find(asset); it != chosen.end()) return it->second;
  const RenderSettings settings;
  CutBuffer full;
  full.upload(h, TreeCut::leaf_cut(h).nodes());
  renderer.draw(full, cam, settings, true);
  const Image reference = grab(renderer);
  auto probe = [&](std::size_t budget) {
    LodChoice c;
    c.budget = budget;
    c.nodes = converged_cut(h, cam, budget);
    CutBuffer lod;
    lod.upload(h, c.nodes);
    renderer.draw(lod, cam, settings, true);
    c.psnr_db = psnr(reference, grab(renderer));
    std::fprintf(stderr, "%s: budget %zu, cut %zu, %.2f dB\n", asset.c_str(), budget,
                 c.nodes.size(), c.psnr_db);
    return c;
  };
  const std::size_t leaves = h.leaf_count();
  std::size_t fail = 0;  // largest budget known to miss 30 dB
  LodChoice best;        // smallest budget known to reach it
  for (std::size_t budget = std::max<std::size_t>(leaves / 64, 1);; budget *= 2) {
    LodChoice c = probe(std::min(budget, leaves));
    if (c.psnr_db >= 30.0 || c.budget >= leaves) {
      best = std::move(c);
      break;
    }
    fail = c.budget;
  }
  while (best.budget - fail > std::max<std::size_t>(best.budget / 64, 1)) {
    LodChoice c = probe(fail + (best.budget - fail) / 2);
    if (c.psnr_db >= 30.0) {
      best = std::move(c);
    } else {
      fail = c.budget;
    }
  }
  return chosen.emplace(asset, std::move(best)).first->second;
}

// The lion scan is z-up, the dragon y-up.
glm::vec3 up_of(const std::string& asset) {
  return asset.rfind("lion", 0) == 0 ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
}

void FullVsLod(benchmark::State& state, const std::string& asset) {
  const Hierarchy* h = model_or_skip(state, asset);
  if (h == nullptr) return;
  context();
  Renderer renderer(*h, kSize);
  const Camera cam = default_camera(h->bounds_min(), h->bounds_max(), kAspect, up_of(asset));
  const LodChoice& choice = lod_choice(asset, *h, renderer, cam);
  CutBuffer lod;
  lod.upload(*h, choice.nodes);
  CutBuffer full;
  full.upload(*h, TreeCut::leaf_cut(*h).nodes());
  const RenderSettings settings;
  FrameTimes full_times, lod_times;
  for (auto _ : state) {
    double seconds = full_times.measure([&] { renderer.draw(full, cam, settings, true); });
    seconds += lod_times.measure([&] { renderer.draw(lod, cam, settings, true); });
    state.SetIterationTime(seconds * 1e-3);
  }
  state.counters["full_ms"] = full_times.median();
  state.counters["lod_ms"] = lod_times.median();
  state.counters["ratio_pct"] = 100.0 * lod_times.median() / full_times.median();
  state.counters["full_cpu_ms"] = full_times.mean_cpu();
  state.counters["lod_cpu_ms"] = lod_times.mean_cpu();
  state.counters["cpu_ratio_pct"] = 100.0 * lod_times.mean_cpu() / full_times.mean_cpu();
  state.counters["full_cut"] = double(full.size());
  state.counters["lod_cut"] = double(lod.size());
  state.counters["psnr_db"] = choice.psnr_db;
}
BENCHMARK_CAPTURE(FullVsLod, dragon, std::string("dragon_vrip.ply"))
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();
BENCHMARK_CAPTURE(FullVsLod, lion, std::string("lion_takanawa.ply"))
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

// Per-range overhead of Renderer::draw_ranges: the dragon's quarter-budget
// optimization cut drawn as one call and as `ranges` equal ranges in
// ascending order with an empty hook between them, frames alternating.
// ns_per_range = (ranges median - one-call median) / ranges, from wall
// times with glFinish, and the same from the render thread's CPU time.
class NoopHook final : public RangeHook {
 public:
  void after_range(std::size_t, const ViewSnapshot&) override { ++calls; }
  std::size_t calls = 0;
};

void RangeOverhead(benchmark::State& state) {
  const Hierarchy* h = model_or_skip(state, "dragon_vrip.ply");
  if (h == nullptr) return;
  context();
  Renderer renderer(*h, kSize);
  const RenderSettings settings;
  const Camera cam = default_camera(h->bounds_min(), h->bounds_max(), kAspect);
  static const std::vector<NodeId> nodes = converged_cut(*h, cam, h->leaf_count() / 4);
  CutBuffer cut;
  cut.upload(*h, nodes);
  const auto n = static_cast<std::uint32_t>(state.range(0));
  std::vector<CutRange> ranges;
  const auto size = static_cast<std::uint32_t>(cut.size());
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t first = static_cast<std::uint32_t>(std::uint64_t{size} * i / n);
    const std::uint32_t end = static_cast<std::uint32_t>(std::uint64_t{size} * (i + 1) / n);
    ranges.push_back({first, end - first});
  }
  NoopHook hook;
  FrameTimes one, many;
  for (auto _ : state) {
    double ms = one.measure([&] { renderer.draw(cut, cam, settings, true); });
    ms += many.measure([&] { renderer.draw_ranges(cut, ranges, cam, settings, &hook, true); });
    state.SetIterationTime(ms * 1e-3);
  }
  state.counters["one_call_ms"] = one.median();
  state.counters["ranges_ms"] = many.median();
  state.counters["ns_per_range"] = (many.median() - one.median()) * 1e6 / double(n);
  state.counters["thread_ns_per_range"] =
      (many.mean_thread() - one.mean_thread()) * 1e6 / double(n);
  state.counters["cut"] = double(cut.size());
  state.counters["hook_calls_per_frame"] =
      double(hook.calls) / double(std::max<std::size_t>(many.wall_ms.size(), 1));
}
BENCHMARK(RangeOverhead)
    ->Arg(10)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

// Fades under a slowly moving camera: the dragon, the optimization strategy
// (budget leaves / arg0), an orbit of arg1 / 1000 degrees per frame. Three
// Controllers run the same path side by side, frame by frame: blend_frames 0,
// 4 and 8, each stage stepped once after every frame outside the frame time
// (as `treecut render --sync`: deterministic). Per frame: the fraction of
// pixels whose RGB changes by more than 8/255 against the previous frame of
// the same controller (image.hpp changed_fraction), and the frame time
// (poll + upload + draw + glFinish). max_changed_* is the largest fraction
// over the path, frame_ms_* the median frame time. With TREECUT_FADE_CSV=DIR
// the per-frame values go to DIR/fades_ARG0_ARG1.csv (tests/bench/fade_plot.py).
// max_changed_frozen: the same path with the first cut frozen (the camera's
// motion alone).
void FadeStability(benchmark::State& state) {
  const Hierarchy* h = model_or_skip(state, "dragon_vrip.ply");
  if (h == nullptr) return;
  context();
  Renderer renderer(*h, kSize);
  const RenderSettings settings;
  const std::size_t budget = h->leaf_count() / static_cast<std::size_t>(state.range(0));
  const Camera cam = default_camera(h->bounds_min(), h->bounds_max(), kAspect);
  const glm::vec3 center = cam.target;
  const float kStep = float(state.range(1)) * 1e-3f * 3.14159265f / 180.0f;
  auto camera_at = [&](std::size_t i) {
    const float angle = kStep * float(i);
    const glm::vec3 off = cam.eye - center;
    Camera c = cam;
    c.eye = center + glm::vec3(off.x * std::cos(angle) - off.z * std::sin(angle), off.y,
                               off.x * std::sin(angle) + off.z * std::cos(angle));
    return c;
  };
  const std::vector<unsigned> blends{0, 4, 8};
  struct Run {
    std::unique_ptr<Controller> ctl;
    CutBuffer cut;
    FrameTimes times;
    Image last;
    std::vector<double> changed;
    std::uint64_t exchanges = 0;
  };
  std::vector<Run> runs(blends.size());
  for (std::size_t b = 0; b < blends.size(); ++b) {
    StageOptions o;
    o.launch = Launch::Manual;
    o.blend_frames = blends[b];
    o.list_buffers = 3;
    runs[b].ctl = std::make_unique<Controller>(make_model(*h), optimization(budget),
                                               snapshot(cam, {0, 0, 1}), o);
    // Untimed: converge at the first camera.
    for (int i = 0; i < 3000; ++i) {
      runs[b].ctl->set_camera(cam.view_matrix(), cam.projection_matrix(kAspect), kSize);
      runs[b].cut.follow(runs[b].ctl->begin_frame());
      if (runs[b].ctl->stage().counters().converged && runs[b].cut.fade() >= 1.0f) break;
      runs[b].ctl->stage().step();
    }
    renderer.draw(runs[b].cut, cam, settings, true);
    runs[b].last = grab(renderer);
  }
  // The motion alone: the first converged cut, frozen, along the same path.
  CutBuffer frozen;
  frozen.upload(*h, runs[0].cut.ids());
  renderer.draw(frozen, cam, settings, true);
  Image frozen_last = grab(renderer);
  std::vector<double> frozen_changed;
  std::size_t frame = 1;
  for (auto _ : state) {
    double seconds = 0.0;
    const Camera c = camera_at(frame++);
    renderer.draw(frozen, c, settings, true);
    Image still = grab(renderer);
    frozen_changed.push_back(changed_fraction(frozen_last, still));
    frozen_last = std::move(still);
    for (Run& r : runs) {
      seconds += r.times.measure([&] {
        r.ctl->set_camera(c.view_matrix(), c.projection_matrix(kAspect), kSize);
        r.cut.follow(r.ctl->begin_frame());
        renderer.draw(r.cut, c, settings, true);
      }) * 1e-3;
      Image img = grab(renderer);
      r.changed.push_back(changed_fraction(r.last, img));
      r.last = std::move(img);
      r.ctl->stage().step();
    }
    state.SetIterationTime(seconds);
  }
  for (std::size_t b = 0; b < blends.size(); ++b) {
    const Run& r = runs[b];
    const std::string k = std::to_string(blends[b]);
    state.counters["max_changed_" + k] =
        r.changed.empty() ? 0.0 : *std::max_element(r.changed.begin(), r.changed.end());
    std::vector<double> sorted = r.changed;
    std::sort(sorted.begin(), sorted.end());
    state.counters["p99_changed_" + k] =
        sorted.empty() ? 0.0 : sorted[std::min(sorted.size() - 1, sorted.size() * 99 / 100)];
    state.counters["mean_changed_" + k] =
        sorted.empty() ? 0.0
                       : std::accumulate(sorted.begin(), sorted.end(), 0.0) / double(sorted.size());
    state.counters["frame_ms_" + k] = r.times.median();
    state.counters["thread_ms_" + k] = r.times.mean_thread();
    state.counters["exchanges_" + k] = double(r.ctl->stage().counters().exchanges);
  }
  state.counters["max_changed_frozen"] =
      frozen_changed.empty() ? 0.0
                             : *std::max_element(frozen_changed.begin(), frozen_changed.end());
  state.counters["cut"] = double(runs[0].cut.size());
  if (const char* dir = std::getenv("TREECUT_FADE_CSV")) {
    const std::string path = std::string(dir) + "/fades_" + std::to_string(state.range(0)) + "_" +
                             std::to_string(state.range(1)) + ".csv";
    std::ostringstream csv;
    csv << "frame,changed_frozen";
    for (const unsigned b : blends) csv << ",changed_" << b << ",frame_ms_" << b;
    csv << '\n';
    char cell[48];
    for (std::size_t i = 0; i < runs[0].changed.size(); ++i) {
      std::snprintf(cell, sizeof cell, "%zu,%.6f", i + 1, frozen_changed[i]);
      csv << cell;
      for (const Run& r : runs) {
        std::snprintf(cell, sizeof cell, ",%.6f,%.3f", r.changed[i], r.times.wall_ms[i]);
        csv << cell;
      }
      csv << '\n';
    }
    try {
      treecut::write_file_atomically(path, csv.str());
    } catch (const std::exception& e) {
      state.SkipWithError(e.what());
    }
  }
}
// Args: budget = leaves / arg0; camera step arg1 / 1000 degrees per frame.
BENCHMARK(FadeStability)
    ->Args({4, 100})
    ->Args({32, 100})
    ->Args({32, 20})
    ->Iterations(240)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

}  // namespace

// Scenes of many objects (issue 13): arg0 objects on a grid, instances of two
// generated models (a sphere and a small city, 2,000 points each), every
// object's cut its 16 coarsest nodes. Per frame: the scene cut's upload
// (SceneCutBuffer::upload: the element list and a command per object), the
// draw's issue on the render thread (draw_scene without glFinish: GL calls,
// and llvmpipe's vertex and geometry stages, which run on the calling
// thread) and the whole frame (+ glFinish). draw_calls is per frame: one per
// pass whatever the objects.
void SceneObjects(benchmark::State& state) {
  context();
  static const Hierarchy sphere = build_from_points(generate_model(ModelKind::Sphere, 2000, 1));
  static const Hierarchy city = build_from_points(generate_model(ModelKind::City, 2000, 2));
  const Hierarchy* models[] = {&sphere, &city};
  const auto objects = static_cast<std::size_t>(state.range(0));
  const auto side = static_cast<std::size_t>(std::ceil(std::sqrt(double(objects))));
  std::vector<SceneObject> draws;
  for (std::size_t i = 0; i < objects; ++i) {
    const glm::vec3 at(3.0f * float(i % side), 3.0f * float(i / side), 0.0f);
    draws.push_back(place_object(static_cast<std::uint32_t>(i % 2), glm::translate(glm::mat4(1.0f), at)));
  }
  const auto coarse = [](const Hierarchy& h) {
    TreeCut cut = TreeCut::root_cut(h);
    for (NodeId n = 0; n < h.node_count() && cut.size() < 16; ++n) {
      if (cut.contains(n) && !h.is_leaf(n)) cut.refine(h, n);
    }
    std::vector<NodeId> v(cut.nodes().begin(), cut.nodes().end());
    std::sort(v.begin(), v.end());
    return v;
  };
  const std::vector<NodeId> cuts_of[] = {coarse(sphere), coarse(city)};
  std::vector<std::span<const NodeId>> cuts;
  for (std::size_t i = 0; i < objects; ++i) cuts.emplace_back(cuts_of[i % 2]);
  Renderer renderer(sphere, kSize);
  renderer.set_models(models);
  SceneCutBuffer buffer;
  buffer.set_objects(renderer, draws);
  const float extent = 3.0f * float(side);
  const Camera cam = fit_camera(glm::vec3(-1.0f), glm::vec3(extent, extent, 2.0f), kAspect,
                                glm::vec3(0.0f, -0.6f, 1.0f), glm::vec3(0, 0, 1));
  const RenderSettings settings;
  // The baseline: as many splats in one cut of one model, drawn plainly (what
  // the splats cost without objects), in the same run.
  static const Hierarchy big = build_from_points(generate_model(ModelKind::City, 2'400'000, 3));
  Renderer plain_renderer(big, kSize);
  CutBuffer plain_cut;
  {
    TreeCut cut = TreeCut::root_cut(big);
    for (NodeId n = 0; n < big.node_count() && cut.size() < 16 * objects; ++n) {
      if (cut.contains(n) && !big.is_leaf(n)) cut.refine(big, n);
    }
    plain_cut.upload(big, cut.nodes());
  }
  const Camera plain_cam = default_camera(big.bounds_min(), big.bounds_max(), kAspect);
  FrameTimes upload, issue, frame, plain_issue;
  std::size_t calls = 0;
  for (auto _ : state) {
    const double ms = frame.measure([&] {
      upload.measure([&] { buffer.upload(models, cuts); });
      issue.measure([&] { calls = renderer.draw_scene(buffer, cam, settings, false).draw_calls; });
      gl::Finish();
    });
    plain_issue.measure([&] { plain_renderer.draw(plain_cut, plain_cam, settings, false); });
    gl::Finish();
    state.SetIterationTime(ms * 1e-3);
  }
  state.counters["plain_splats"] = double(plain_cut.size());
  state.counters["plain_issue_render_thread_ms"] = plain_issue.mean_thread();
  state.counters["objects"] = double(objects);
  state.counters["splats"] = double(buffer.size());
  state.counters["draw_calls"] = double(calls);
  state.counters["upload_render_thread_ms"] = upload.mean_thread();
  state.counters["issue_render_thread_ms"] = issue.mean_thread();
  state.counters["frame_ms"] = frame.median();
}
BENCHMARK(SceneObjects)->Arg(1000)->Arg(100000)->Unit(benchmark::kMillisecond)->UseManualTime();

BENCHMARK_MAIN();
