// Many objects (strategies/include/treecut/strategies/{hzm,budget}.hpp; Peng &
// Cao, I3D 2013, sections 5-6): time per frame of the culling phases
// (projection and frustum culling, occluder selection, HZM build, the
// tests) and of the budget (Eq. 1), on seeded box cities of 10,000 and
// 100,000 buildings seen from 8 street-level cameras at 1280 x 720, with a
// worker pool of 1 and 2 threads; and the culling accuracy against the
// exact CPU reference (objects culled / objects truly hidden; the paper:
// 58.3 %).
//
// Each iteration is one frame of one camera (the 8 in turn); the reported
// time (manual) is select + cull = project + select + hzm + test, wall
// clock; the counters are each phase's mean wall milliseconds and the
// process CPU milliseconds (all threads) of the culling and the budget. Accuracy counters
// come from one pass over the 8 cameras before timing (the reference is
// slow and not part of a frame).
//
//   build/NAME/tests/bench/many_objects_bench --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
//
// Arguments: objects, threads, depth_width (cells across the larger side
// of the viewport; 1280 = one cell per pixel), AOS size.
#include <benchmark/benchmark.h>
#include <time.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <map>
#include <memory>
#include <tuple>

#include "test_support.hpp"
#include "treecut/culling/hzm.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/strategies/budget.hpp"
#include "treecut/strategies/budget_strategy.hpp"
#include "treecut/tools/scene_generate.hpp"
#include "treecut/tools/walk_path.hpp"

namespace {

using namespace treecut::strategies::many;
using namespace treecut::culling;
using treecut::WorkerPool;
using Clock = std::chrono::steady_clock;

constexpr std::uint32_t kSeed = 1;
constexpr std::size_t kViews = 8;

struct City {
  std::vector<ObjectBounds> objects;
  std::vector<treecut::ViewSnapshot> views;
};

const City& city(std::size_t count) {
  static std::map<std::size_t, std::unique_ptr<City>> cache;
  auto& slot = cache[count];
  if (!slot) {
    slot = std::make_unique<City>();
    slot->objects = box_city(count, kSeed);
    slot->views = city_views(count, kViews, kSeed, {1280, 720});
  }
  return *slot;
}

// The exact reference per camera, computed once per city.
const std::vector<std::vector<std::uint8_t>>& reference(std::size_t count) {
  static std::map<std::size_t, std::vector<std::vector<std::uint8_t>>> cache;
  auto& slot = cache[count];
  if (slot.empty()) {
    const City& c = city(count);
    WorkerPool pool(2);
    for (const auto& v : c.views) {
      slot.emplace_back();
      reference_visibility(c.objects, v, slot.back(), &pool);
    }
  }
  return slot;
}

double ms(Clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

// CPU time of the whole process (the pool's threads), milliseconds: on a
// machine shared with other builds the wall clock also counts waiting for
// a core.
double thread_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}
double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

void BM_Frame(benchmark::State& state) {
  const auto count = static_cast<std::size_t>(state.range(0));
  const auto threads = static_cast<unsigned>(state.range(1));
  HzmParams params;
  params.depth_width = static_cast<unsigned>(state.range(2));
  params.active = static_cast<std::size_t>(state.range(3));
  params.facing = state.range(4) ? Facing::EyeToObject : Facing::ViewDirection;
  params.finer_levels = static_cast<int>(state.range(5));
  const City& c = city(count);
  const auto& ref = reference(count);
  WorkerPool pool(threads);
  HzmCuller culler(params);
  culler.preprocess(c.objects);

  // Accuracy over the 8 cameras (untimed).
  CullAccuracy total;
  std::size_t in_frustum = 0, visible = 0, seen = 0;
  for (std::size_t v = 0; v < c.views.size(); ++v) {
    culler.cull(c.objects, c.views[v], &pool);
    const CullAccuracy a = cull_accuracy(culler, ref[v]);
    total.culled += a.culled;
    total.hidden += a.hidden;
    total.wrongly += a.wrongly;
    total.subpixel += a.subpixel;
    const CullStats s = culler.stats();
    in_frustum += s.in_frustum;
    visible += s.visible;
    for (const std::uint8_t x : ref[v]) seen += x;
  }

  BudgetParams budget;
  budget.total = 10'000'000;
  std::vector<BudgetItem> items;
  std::vector<std::uint32_t> shares;
  double t_project = 0, t_select = 0, t_hzm = 0, t_test = 0, t_budget = 0;
  double cpu_main = 0, cpu_cull = 0, cpu_budget = 0, cpu_project = 0, cpu_select = 0, cpu_hzm = 0,
         cpu_test = 0;
  std::size_t frame = 0;
  for (auto _ : state) {
    const treecut::ViewSnapshot& view = c.views[frame++ % c.views.size()];
    const double c0 = cpu_ms();
    const double m0 = thread_cpu_ms();
    const auto t0 = Clock::now();
    culler.project(c.objects, view, &pool);
    const auto t1 = Clock::now();
    const double c1 = cpu_ms();
    culler.select_occluders(c.objects, view, &pool);
    const auto t2 = Clock::now();
    const double c2 = cpu_ms();
    culler.build_hzm(c.objects, view, &pool);
    const auto t3 = Clock::now();
    const double c3 = cpu_ms();
    culler.test(c.objects, &pool);
    const auto t4 = Clock::now();
    const double c4 = cpu_ms();
    cpu_main += thread_cpu_ms() - m0;
    budget_items(c.objects, culler.rects(), culler.visible(), items, &pool);
    allocate_budget(items, budget, shares, &pool);
    const auto t5 = Clock::now();
    cpu_budget += cpu_ms() - c4;
    cpu_cull += c4 - c0;
    cpu_project += c1 - c0;
    cpu_select += c2 - c1;
    cpu_hzm += c3 - c2;
    cpu_test += c4 - c3;
    benchmark::DoNotOptimize(shares.data());
    t_project += ms(t1 - t0);
    t_select += ms(t2 - t1);
    t_hzm += ms(t3 - t2);
    t_test += ms(t4 - t3);
    t_budget += ms(t5 - t4);
    state.SetIterationTime(std::chrono::duration<double>(t4 - t0).count());
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["project_ms"] = t_project / n;
  state.counters["select_ms"] = t_select / n;
  state.counters["hzm_ms"] = t_hzm / n;
  state.counters["test_ms"] = t_test / n;
  state.counters["budget_ms"] = t_budget / n;
  state.counters["cull_cpu_ms"] = cpu_cull / n;
  // The calling thread's part of it (1/2 when the two threads share evenly).
  state.counters["cull_main_share"] = cpu_cull > 0 ? cpu_main / cpu_cull : 0.0;
  state.counters["budget_cpu_ms"] = cpu_budget / n;
  state.counters["project_cpu_ms"] = cpu_project / n;
  state.counters["select_cpu_ms"] = cpu_select / n;
  state.counters["hzm_cpu_ms"] = cpu_hzm / n;
  state.counters["test_cpu_ms"] = cpu_test / n;
  state.counters["culled"] = static_cast<double>(total.culled) / kViews;
  state.counters["hidden"] = static_cast<double>(total.hidden) / kViews;
  state.counters["subpixel"] = static_cast<double>(total.subpixel) / kViews;
  state.counters["wrongly"] = static_cast<double>(total.wrongly);
  state.counters["accuracy"] =
      total.hidden ? static_cast<double>(total.culled) / static_cast<double>(total.hidden) : 1.0;
  const std::size_t occluded_beyond_pixels = total.hidden - total.subpixel;
  state.counters["accuracy_px"] =
      occluded_beyond_pixels
          ? static_cast<double>(total.culled) / static_cast<double>(occluded_beyond_pixels)
          : 1.0;
  state.counters["in_frustum"] = static_cast<double>(in_frustum) / kViews;
  state.counters["visible"] = static_cast<double>(visible) / kViews;
  state.counters["seen"] = static_cast<double>(seen) / kViews;
}

BENCHMARK(BM_Frame)
    ->ArgNames({"objects", "threads", "depth", "aos", "to_object", "finer"})
    ->ArgsProduct({{10000, 100000}, {1, 2}, {320, 1280}, {32}, {1}, {0, 2}})
    ->ArgsProduct({{100000}, {2}, {320}, {16, 64}, {1}, {2}})
    ->ArgsProduct({{10000, 100000}, {2}, {320}, {32}, {0}, {2}})
    ->ArgsProduct({{100000}, {2}, {320}, {32}, {1}, {1, 3, 10}})
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

// The budget strategy itself on the generated city block (`treecut gen
// city-block --objects N`, 20,000 points a model, seed 1) along its walk
// (`gen --walk`), as `treecut render SCENE -s budget --sync --frames 6`
// samples it: 6 frames at t = k / 5 of the walk, clip planes fitted to the
// scene. Each iteration is one iterate_scene (N = 1,000,000 points) of the
// next of the 6 views; the reported time is select + cull (everything but
// best_cut) wall, the counters each phase's wall and CPU (stage thread +
// pool workers, BudgetCounters) per iteration.
struct CityBlock {
  treecut::Scene scene;
  std::shared_ptr<const treecut::StageScene> stage;
  std::vector<treecut::ViewSnapshot> views;
};

const CityBlock& city_block(std::size_t buildings) {
  static std::map<std::size_t, std::unique_ptr<CityBlock>> cache;
  auto& slot = cache[buildings];
  if (!slot) {
    slot = std::make_unique<CityBlock>();
    const treecut::tools::CityBlockLayout layout =
        treecut::tools::city_block_layout(buildings, kSeed);
    const std::filesystem::path file = treecut::test::scratch_dir("many_objects_bench") /
                                       ("city" + std::to_string(buildings) + ".scene");
    {
      std::ofstream out(file);
      out << treecut::tools::format_city_block_scene(layout, kSeed, 20000);
      if (!out.flush()) throw std::runtime_error(file.string() + ": cannot write");
    }
    treecut::SceneLoadOptions options;
    options.parse.generator = treecut::tools::scene_generator();
    slot->scene = treecut::load_scene(file, options);
    slot->stage = treecut::stage_scene(slot->scene);
    const treecut::splat::CameraPath path =
        treecut::tools::walk_path(treecut::tools::city_block_walkthrough(layout));
    const glm::vec3 lo = slot->scene.bounds_min, hi = slot->scene.bounds_max;
    const glm::vec3 center = 0.5f * (lo + hi);
    const float radius = std::max(0.5f * glm::length(hi - lo), 1e-6f);
    constexpr int kFrames = 6;
    for (int f = 0; f < kFrames; ++f) {
      treecut::splat::Camera c = path.at(path.duration() * f / (kFrames - 1));
      treecut::splat::fit_clip_planes(c, center, radius);
      slot->views.push_back(treecut::splat::view_snapshot(c, {1280, 720}, {}));
    }
  }
  return *slot;
}

void BM_CityBlock(benchmark::State& state) {
  const auto buildings = static_cast<std::size_t>(state.range(0));
  const CityBlock& cb = city_block(buildings);
  treecut::strategies::BudgetStrategy s;
  s.set_param("threads", static_cast<double>(state.range(1)));
  s.set_param("culling", static_cast<double>(state.range(2)));
  s.set_param("points", 1'000'000.0);
  s.reset_scene(*cb.stage);
  std::vector<treecut::NodeId> nodes, previous;
  std::vector<std::uint32_t> offsets, previous_offsets;
  double w[6] = {}, c[6] = {};
  double visible = 0, culled = 0, selected = 0;
  std::size_t frame = 0;
  const auto ms_of = [](std::uint64_t ns) { return static_cast<double>(ns) * 1e-6; };
  for (auto _ : state) {
    const treecut::ViewSnapshot& view = cb.views[frame++ % cb.views.size()];
    treecut::SceneIterationInput in{*cb.stage, view, nullptr, 0, previous, previous_offsets};
    treecut::SceneIterationOutput out;
    out.nodes = &nodes;
    out.offsets = &offsets;
    nodes.clear();
    s.iterate_scene(in, out);
    const treecut::strategies::BudgetCounters& k = s.last();
    const std::uint64_t wall[6] = {k.project_ns, k.select_ns, k.hzm_ns,
                                   k.test_ns,    k.budget_ns, k.lod_ns};
    const std::uint64_t cpu[6] = {k.project_cpu_ns, k.select_cpu_ns, k.hzm_cpu_ns,
                                  k.test_cpu_ns,    k.budget_cpu_ns, k.lod_cpu_ns};
    for (int i = 0; i < 6; ++i) {
      w[i] += ms_of(wall[i]);
      c[i] += ms_of(cpu[i]);
    }
    visible += static_cast<double>(k.visible);
    culled += static_cast<double>(k.occlusion_culled);
    selected += static_cast<double>(k.selected);
    state.SetIterationTime(
        static_cast<double>(k.project_ns + k.select_ns + k.hzm_ns + k.test_ns + k.budget_ns) *
        1e-9);
  }
  const double n = static_cast<double>(state.iterations());
  const char* names[6] = {"project", "select", "hzm", "test", "eq1", "lod"};
  for (int i = 0; i < 6; ++i) {
    state.counters[std::string(names[i]) + "_ms"] = w[i] / n;
    state.counters[std::string(names[i]) + "_cpu_ms"] = c[i] / n;
  }
  state.counters["select_cull_cpu_ms"] = (c[0] + c[1] + c[2] + c[3] + c[4]) / n;
  state.counters["objects"] = static_cast<double>(cb.stage->objects.size());
  state.counters["visible"] = visible / n;
  state.counters["occluded"] = culled / n;
  state.counters["selected"] = selected / n;
}

BENCHMARK(BM_CityBlock)
    ->ArgNames({"buildings", "threads", "culling"})
    ->ArgsProduct({{20000, 100000}, {1, 2}, {1}})
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

}  // namespace

BENCHMARK_MAIN();
