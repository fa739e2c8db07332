// The GPU query executor (treecut/splat/query_executor.hpp) on OSMesa
// (llvmpipe), 1280x720, fast splats, a generated terrain of 200,000 points
// drawn as the cut of one hierarchy level (the same draws in every frame).
//
//  - Queries/n:N/points:P/batch:B: frames alternate between "off" (the cut
//    alone, with a hook that issues nothing) and "on" (the cut and N
//    queries: every "on" frame a new list generation of N requests about
//    nodes of the drawn cut). The executor counts only the "on" frames (its
//    frame numbers 1, 2, 3, ...): the "off" frames are the control, run
//    interleaved so that both see the same load, as if every frame had
//    queries. B = 1: the executor's minimum batch (defaults: min_batch 256,
//    max_defer_frames 1: a trickle of N < 256 goes out every other "on"
//    frame as one batch of 2N); B = 0: min_batch 1 (a batch every frame,
//    the executor before batching).
//    us_per_query_median / _max: per WINDOW, the executor's render-thread
//    CPU time (thread CPU clock: issue + poll + the batch's fence,
//    QueryStats::cpu_ns_last) summed over the "on" frames of the window,
//    divided by the requests posted in them; a window ends with the frame
//    that emptied the queue (the batching period: 2 frames for N < 256, 1
//    from 256 on, 1 for B = 0), so a frame that only polls charges its cost
//    to the requests it deferred and a batch's cost is never hidden
//    (target <= 2 us). frame_us_per_query_max: the largest single "on"
//    frame's executor CPU / N (not charged over the window).
//    wall_us_per_query_*: the same per window as wall time (a wait inside
//    the executor would show here and not in the CPU time).
//    frame_ms_{on,off} median and max: wall time of a frame (draw with the
//    queries inside, glFinish); max_ratio = max on / max off, median_ratio
//    the same for medians (target <= 1.2: a frame never waits for a query);
//    frame_cpu_ms_*: the render thread's CPU time of a frame. latency: mean
//    and max executor frames from the REQUEST to the read (the deferral
//    included; 1 without it).
//    P = 1 (the registered runs): point proxies where they fit (the
//    default), 0: every proxy a quad (QueryExecutorOptions::point_proxies);
//    point_share: of the proxies.
//    tail_us_{on,off}_median: render-thread CPU from the hook's return to
//    the end of the frame (glFinish): where a frame without queries would pay
//    work of the cut that the executor's first draw made happen earlier;
//    added_us_per_query_median = (executor + tail of "on" frames - tail of
//    "off" frames) / N, medians: the render-thread CPU the queries add.
//
// Run: build/perf/tests/bench/query_bench
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <memory>
#include <vector>

#include "bench_models.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/query_executor.hpp"
#include "treecut/splat/renderer.hpp"

namespace treecut::bench {
namespace {

constexpr int kWidth = 1280;
constexpr int kHeight = 720;

splat::GlContext& context() {
  static const std::unique_ptr<splat::GlContext> ctx =
      splat::make_headless_context(kWidth, kHeight);
  ctx->make_current();
  return *ctx;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

std::uint64_t thread_cpu_ns() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return std::uint64_t(t.tv_sec) * 1'000'000'000u + std::uint64_t(t.tv_nsec);
}

double max_of(const std::vector<double>& v) {
  return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
}

void Queries(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  context();
  const std::shared_ptr<const Hierarchy> h = generated(tools::ModelKind::Terrain, 200'000);
  splat::Renderer renderer(*h, {kWidth, kHeight});
  // A level with at least 20,000 nodes (or the leaves): the drawn cut.
  int level = 0;
  while (level + 1 < h->level_count() &&
         h->level_begin(level + 1) - h->level_begin(level) < 20'000) {
    ++level;
  }
  std::vector<NodeId> cut_nodes;
  for (NodeId id = h->level_begin(level); id < h->level_begin(level + 1); ++id) {
    cut_nodes.push_back(id);
  }
  splat::CutBuffer cut;
  cut.upload(*h, cut_nodes);
  const splat::Camera cam = splat::default_camera(h->bounds_min(), h->bounds_max(),
                                                  float(kWidth) / float(kHeight), {0, 0, 1});
  splat::QueryExecutorOptions eo;
  // Never the limit here (a batch holds up to 2N): the cap is not measured.
  eo.max_issue_per_frame = std::max<std::size_t>(2 * n, 4096);
  eo.point_proxies = state.range(1) != 0;
  if (state.range(2) == 0) eo.min_batch = 1;
  splat::QueryExecutor executor(eo);
  // N requests about nodes spread over the cut.
  std::vector<QueryRequest> requests;
  for (std::size_t i = 0; i < n; ++i) {
    const NodeId node = cut_nodes[(i * 7919) % cut_nodes.size()];
    requests.push_back({0, node, static_cast<std::uint32_t>(i), QueryKind::Samples,
                        h->arrays().center_radius[node]});
  }
  FrontList list;
  list.hierarchy = h.get();
  list.queries = requests;
  std::uint64_t frame = 0;
  std::uint64_t executor_frame = 0;  // counts the "on" frames only
  std::vector<double> on_ms, off_ms, on_cpu_ms, off_cpu_ms, per_query_us, per_query_wall_us,
      poll_us, tail_on_us, tail_off_us, on_hook_tail_us, frame_per_query_us;
  double window_cpu_ns = 0.0, window_wall_ns = 0.0, window_requests = 0.0;
  const splat::RenderSettings settings;
  double frame_cpu_ms = 0.0;
  // Installed in every frame (the "off" frames: a hook that issues nothing,
  // so both kinds of frame make the same state changes around it); records
  // the render thread's CPU clock around the executor's run().
  struct TimedHook final : splat::QueryHook {
    splat::QueryHook* inner = nullptr;
    std::uint64_t enter = 0, exit = 0;
    void run(const ViewSnapshot& view) override {
      enter = thread_cpu_ns();
      if (inner != nullptr) inner->run(view);
      exit = thread_cpu_ns();
    }
  } timed;
  renderer.set_query_hook(&timed);
  double frame_tail_us = 0.0;
  auto run_frame = [&](bool queries) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::uint64_t c0 = thread_cpu_ns();
    ++frame;
    timed.inner = nullptr;
    if (queries) {
      list.generation = frame;  // a new list every "on" frame: N requested per frame
      executor.begin_frame_render_thread(list, ++executor_frame);
      timed.inner = &executor;
    }
    renderer.draw(cut, cam, settings, true);
    executor.clear_results();
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const std::uint64_t c1 = thread_cpu_ns();
    frame_cpu_ms = double(c1 - c0) * 1e-6;
    // After the hook to the end of glFinish: where a frame pays llvmpipe's
    // deferred vertex work of the cut when no proxy draw made it pay earlier.
    frame_tail_us = double(c1 - timed.exit) * 1e-3;
    return ms;
  };
  for (int i = 0; i < 4; ++i) {  // warm-up: pool grown, caches hot
    run_frame(true);
    run_frame(false);
  }
  // Measured windows start at a window's start: run "on" frames until the
  // queue is empty (a batch just went out).
  for (int i = 0; i < 8 && executor.stats().queued != 0; ++i) {
    run_frame(true);
    run_frame(false);
  }
  const std::uint64_t answered0 = executor.stats().answered;
  const std::uint64_t latency0 = executor.stats().latency_frames_total;
  for (auto _ : state) {
    const double on = run_frame(true);
    on_cpu_ms.push_back(frame_cpu_ms);
    tail_on_us.push_back(frame_tail_us);
    on_hook_tail_us.push_back(double(executor.stats().cpu_ns_last) * 1e-3 + frame_tail_us);
    if (n > 0) {
      const splat::QueryStats& q = executor.stats();
      window_cpu_ns += double(q.cpu_ns_last);
      window_wall_ns += double(q.wall_ns_last);
      window_requests += double(n);
      frame_per_query_us.push_back(double(q.cpu_ns_last) * 1e-3 / double(n));
      poll_us.push_back(double(q.poll_ns_last) * 1e-3 / double(n));
      if (q.queued == 0) {  // the queue emptied: the window (batching period) ends
        per_query_us.push_back(window_cpu_ns * 1e-3 / window_requests);
        per_query_wall_us.push_back(window_wall_ns * 1e-3 / window_requests);
        window_cpu_ns = window_wall_ns = window_requests = 0.0;
      }
    }
    on_ms.push_back(on);
    off_ms.push_back(run_frame(false));
    off_cpu_ms.push_back(frame_cpu_ms);
    tail_off_us.push_back(frame_tail_us);
  }
  const double on_max = max_of(on_ms);
  const double off_max = max_of(off_ms);
  state.counters["cut_nodes"] = double(cut_nodes.size());
  state.counters["frame_ms_on_median"] = median(on_ms);
  state.counters["frame_ms_off_median"] = median(off_ms);
  state.counters["frame_ms_on_max"] = on_max;
  state.counters["frame_ms_off_max"] = off_max;
  state.counters["max_ratio"] = on_max / off_max;
  state.counters["median_ratio"] = median(on_ms) / median(off_ms);
  state.counters["frame_cpu_ms_on_median"] = median(on_cpu_ms);
  state.counters["frame_cpu_ms_off_median"] = median(off_cpu_ms);
  state.counters["cpu_max_ratio"] = max_of(on_cpu_ms) / max_of(off_cpu_ms);
  if (n > 0) {
    state.counters["us_per_query_median"] = median(per_query_us);
    state.counters["us_per_query_max"] = max_of(per_query_us);
    state.counters["windows"] = double(per_query_us.size());
    state.counters["frame_us_per_query_max"] = max_of(frame_per_query_us);
    state.counters["batches_per_frame"] =
        double(executor.stats().batches) / double(std::max<std::uint64_t>(executor_frame, 1));
    state.counters["wall_us_per_query_median"] = median(per_query_wall_us);
    state.counters["wall_us_per_query_max"] = max_of(per_query_wall_us);
    state.counters["poll_us_per_query_median"] = median(poll_us);
    const std::uint64_t answered = executor.stats().answered - answered0;
    state.counters["latency_frames_mean"] =
        answered == 0 ? 0.0
                      : double(executor.stats().latency_frames_total - latency0) / double(answered);
    state.counters["latency_frames_max"] = double(executor.stats().latency_frames_max);
    // The executor's CPU plus the frame's rest after it, against the rest
    // of a frame without queries: the render-thread CPU the queries add.
    state.counters["tail_us_on_median"] = median(tail_on_us);
    state.counters["tail_us_off_median"] = median(tail_off_us);
    state.counters["added_us_per_query_median"] =
        (median(on_hook_tail_us) - median(tail_off_us)) / double(n);
    state.counters["dropped"] = double(executor.stats().dropped);
    state.counters["point_share"] = double(executor.stats().point_proxies) /
                                    double(std::max<std::uint64_t>(executor.stats().issued, 1));
  }
}
BENCHMARK(Queries)
    ->ArgNames({"n", "points", "batch"})
    ->ArgsProduct({{1, 10, 100, 10'000}, {1}, {1, 0}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(60);

}  // namespace
}  // namespace treecut::bench

BENCHMARK_MAIN();
