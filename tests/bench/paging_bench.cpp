// Paged drawing's selection (issue 45, treecut/paged_hierarchy.hpp): the
// Feedback Stage's iterations along a flight low over the large generated
// terrain, once on the model held whole and once drawn from its cache's
// pages within a memory budget, its pages read by an I/O thread while the
// frames go on at 60 a second (no frame waits for one). Per frame the wall time of the
// stage's Process (on the paged model: publish, iterate, ask, give back);
// the ratios are of the two runs of one benchmark, made one after the other.
//
//   paging_bench [--benchmark_filter=...]
//   TREECUT_BENCH_POINTS=2000000 TREECUT_PAGING_MIB=32 paging_bench
//
// The budget is TREECUT_PAGING_MIB, or an eighth of the whole model's node
// arrays. Counters: the medians and 99th percentiles (ms), their ratios
// (paged / whole), the most resident MiB against the budget, the groups of
// pages read and given back, the frames whose cut still wanted pages and
// those whose pages did not fit beside what the lists held (memory short).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench_models.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/strategies/builtin.hpp"

namespace {

using namespace treecut;

constexpr int kFrames = 300;
const char* const kStrategies[] = {"recursive", "event_queue", "optimization", "hoq"};

// Frame F of the flight: from one corner of the terrain to the other at a
// tenth of its height above its top, looking ahead and down.
ViewSnapshot flight(const Hierarchy& h, int f) {
  const glm::vec3 lo = h.bounds_min(), hi = h.bounds_max();
  const float ext = glm::length(hi - lo);
  const float t = float(f) / float(kFrames - 1);
  const glm::vec3 eye(lo.x + (hi.x - lo.x) * (0.1f + 0.8f * t),
                      lo.y + (hi.y - lo.y) * (0.15f + 0.7f * t), hi.z + 0.1f * ext);
  const glm::vec3 ahead = glm::normalize(glm::vec3(hi.x - lo.x, 0.875f * (hi.y - lo.y), 0.0f));
  const glm::vec3 target = eye + 0.2f * ext * ahead - glm::vec3(0.0f, 0.0f, 0.15f * ext);
  ViewSnapshot v = ViewSnapshot::look_at(eye, target, {1280, 720}, 0.9f, 0.001f * ext, 4.0f * ext);
  v.version = static_cast<std::uint64_t>(f) + 1;
  return v;
}

double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * double(v.size())))];
}

struct Run {
  std::vector<double> ms;  // each frame's Process
  double peak_mib = 0.0;
  int wanting = 0;  // frames whose iteration wanted pages
  int short_of = 0;  // frames whose pages did not fit beside the lists (memory_short)
};

Run fly(Model model, const std::string& strategy, const Hierarchy& h) {
  StageOptions o;
  o.launch = Launch::Manual;
  const std::shared_ptr<PagedHierarchy> paged = model.paged;
  FeedbackStage stage(std::move(model), strategies::builtin_registry().create(strategy), o);
  Run run;
  // Frames at 60 a second, as a viewer shows them: the pages are read
  // meanwhile (a frame that ends early waits for its tick, not for a page).
  const auto start = std::chrono::steady_clock::now();
  for (int f = 0; f < kFrames; ++f) {
    std::this_thread::sleep_until(start + f * std::chrono::microseconds(16667));
    stage.set_view(flight(h, f));
    stage.poll();
    const auto t0 = std::chrono::steady_clock::now();
    stage.step();
    run.ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (!paged) continue;
    run.peak_mib = std::max(run.peak_mib, double(paged->stats().resident_bytes) / (1 << 20));
    stage.poll();
    const Counters& c = stage.counters().last.counters;
    if (c.find("pages_wanted").value_or(0.0) > 0.0) ++run.wanting;
    if (c.find("pages_memory_short").value_or(0.0) > 0.0) ++run.short_of;
  }
  return run;
}

void BM_Paging(benchmark::State& state) {
  const std::string strategy = kStrategies[state.range(0)];
  const std::size_t points = bench::large_cloud_points();
  const std::shared_ptr<const Hierarchy> whole =
      bench::generated(tools::ModelKind::Terrain, points);
  const auto cache =
      bench::cache_dir() / ("generated-" + std::to_string(int(tools::ModelKind::Terrain)) + "-" +
                            std::to_string(points) + ".tch");
  PagingOptions options;
  const std::uint64_t per_node = PagedHierarchy::open(cache)->bytes_per_node();
  const char* mib = std::getenv("TREECUT_PAGING_MIB");
  options.memory_bytes =
      mib && *mib ? std::strtoull(mib, nullptr, 10) << 20 : whole->node_count() * per_node / 8;
  for (auto _ : state) {
    const Run held = fly(Model{whole, TreeCut::root_cut(*whole), nullptr}, strategy, *whole);
    const auto t0 = std::chrono::steady_clock::now();
    std::shared_ptr<PagedHierarchy> paged = PagedHierarchy::open(cache, options);
    const double open_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const Run run = fly(make_paged_model(paged), strategy, paged->hierarchy());
    const PagingStats s = paged->stats();
    auto& c = state.counters;
    c["whole_p50_ms"] = percentile(held.ms, 0.5);
    c["whole_p99_ms"] = percentile(held.ms, 0.99);
    c["paged_p50_ms"] = percentile(run.ms, 0.5);
    c["paged_p99_ms"] = percentile(run.ms, 0.99);
    c["ratio_p50"] = c["paged_p50_ms"] / c["whole_p50_ms"];
    c["ratio_p99"] = c["paged_p99_ms"] / c["whole_p99_ms"];
    c["open_ms"] = open_ms;
    c["budget_mib"] = double(options.memory_bytes) / (1 << 20);
    c["model_mib"] = double(whole->node_count() * per_node) / (1 << 20);
    c["peak_mib"] = run.peak_mib;
    c["loaded"] = double(s.loaded);
    c["evicted"] = double(s.evicted);
    c["wanting_frames"] = run.wanting;
    c["short_frames"] = run.short_of;
  }
}

BENCHMARK(BM_Paging)->DenseRange(0, 3)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
