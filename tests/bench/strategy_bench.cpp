// Iteration time per strategy against cut size ("Parallel TreeCut
// Manipulation", figure 6): ns per cut node (optimization, bucket) or per
// visited node (recursive), on the dragon and a generated 20 M-point terrain.
// The camera (and light) turn a little every iteration, so every iteration
// does real work; times are the thread CPU time of iterate() alone (manual
// timing), which a busy machine does not inflate.
//
//   strategy_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <random>
#include <vector>

#include "bench_models.hpp"
#include "treecut/model.hpp"
#include "treecut/strategies/bucket.hpp"
#include "treecut/strategies/optimization.hpp"
#include "treecut/strategies/recursive.hpp"

namespace treecut::bench {
namespace {

ViewSnapshot orbit(const Hierarchy& h, float angle, std::uint64_t version, float factor = 1.6f) {
  const glm::vec3 center = 0.5f * (h.bounds_min() + h.bounds_max());
  const float extent = glm::length(h.bounds_max() - h.bounds_min());
  const glm::vec3 eye =
      center + factor * extent * glm::vec3(std::cos(angle), 0.6f, std::sin(angle));
  ViewSnapshot v =
      ViewSnapshot::look_at(eye, center, {1920, 1080}, 0.8f, 0.001f * extent, 10.0f * extent);
  v.version = version;
  return v;
}

// The cut a long session leaves behind: its order is arbitrary (refines
// append children, coarsens move the last node into the gap), so the
// benchmark starts from the breadth-first cut in a random order.
TreeCut scrambled_cut(const Hierarchy& h, std::size_t n) {
  const TreeCut bfs = breadth_first_cut(h, n);
  std::vector<NodeId> nodes(bfs.nodes().begin(), bfs.nodes().end());
  std::mt19937 rng(7);
  std::shuffle(nodes.begin(), nodes.end(), rng);
  return TreeCut::from_nodes(h, nodes);
}

std::shared_ptr<const Hierarchy> model(int which) {
  static std::shared_ptr<const Hierarchy> models[2];
  if (!models[which]) {
    models[which] =
        which == 0 ? dragon() : generated(tools::ModelKind::Terrain, large_cloud_points());
  }
  return models[which];
}

struct Timing {
  double ns = 0;
  double nodes = 0;
  double cut = 0;
  double ops = 0;
  std::uint64_t iterations = 0;

  void add(double iteration_ns, const IterationResult& r) {
    ns += iteration_ns;
    nodes += static_cast<double>(r.visited);
    cut += static_cast<double>(r.cut_size);
    ops += static_cast<double>(r.refined + r.coarsened);
    ++iterations;
  }
};

void report(benchmark::State& state, const Timing& t) {
  const auto n = static_cast<double>(t.iterations);
  state.counters["ns_per_node"] = t.ns / t.nodes;
  state.counters["cut_size"] = t.cut / n;
  state.counters["ops_per_iter"] = t.ops / n;
}

// Before timing: iterate under the first view until converged (at most 100
// iterations), then 20 iterations of the turning camera or light, so the
// measurement is the steady state of the motion, not the one-time move from
// the starting cut to the strategy's own. `step(i)` runs iteration i of the
// motion (0 = the first view); returns the first iteration to time.
template <typename Step>
std::uint64_t warm_up(Step&& step) {
  for (int i = 0; i < 100 && !step(0).converged; ++i) {
  }
  constexpr std::uint64_t kMoving = 20;
  for (std::uint64_t i = 1; i <= kMoving; ++i) step(i);
  return kMoving + 1;
}

double thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e9 + static_cast<double>(ts.tv_nsec);
}

// Thread CPU time of f(): an iteration is single-threaded, and the CPU time
// does not count the time the thread waited for a core on a shared machine.
template <typename F>
double timed(F&& f) {
  const double t0 = thread_cpu_ns();
  f();
  return thread_cpu_ns() - t0;
}

// Times an evolving strategy on `cut`: warm_up(), then one iterate() per
// benchmark iteration under view_at(i), the i-th view of the motion.
template <typename ViewAt>
void time_evolving(benchmark::State& state, const Hierarchy& h, Strategy& s, TreeCut& cut,
                   ViewAt&& view_at) {
  std::vector<NodeId> unused;
  std::vector<QueryRequest> queries;
  double ns = 0;
  const auto step = [&](std::uint64_t iteration) {
    const ViewSnapshot v = view_at(iteration);
    IterationOutput out;
    out.cut = &cut;
    out.nodes = &unused;
    out.queries = &queries;
    ns = timed([&] { s.iterate(IterationInput{h, v}, out); });
    return out.result;
  };
  const std::uint64_t first = warm_up(step);
  Timing t;
  for (auto _ : state) {
    const IterationResult r = step(first + t.iterations);
    state.SetIterationTime(ns * 1e-9);
    t.add(ns, r);
  }
  report(state, t);
}

// Arguments: model (0 dragon, 1 terrain), cut size.
void BM_Optimization(benchmark::State& state) {
  const auto h = model(static_cast<int>(state.range(0)));
  if (!h) return state.SkipWithError("../shared/assets/dragon_vrip_normals.ply is absent");
  const auto n = static_cast<std::size_t>(state.range(1));
  if (n > h->leaf_count()) return state.SkipWithError("cut larger than the model");
  strategies::OptimizationStrategy s;
  s.set_param("max_nodes", static_cast<double>(n));
  s.set_param("k", 8192);
  s.set_param("min_size", 0.0);
  s.reset(*h);
  TreeCut cut = scrambled_cut(*h, n);
  time_evolving(state, *h, s, cut, [&](std::uint64_t i) {
    return orbit(*h, 0.01f * static_cast<float>(i), i);  // the camera turns
  });
}

void BM_Bucket(benchmark::State& state) {
  const auto h = model(static_cast<int>(state.range(0)));
  if (!h) return state.SkipWithError("../shared/assets/dragon_vrip_normals.ply is absent");
  const auto n = static_cast<std::size_t>(state.range(1));
  if (n > h->leaf_count()) return state.SkipWithError("cut larger than the model");
  TreeCut cut = scrambled_cut(*h, n);
  // Buckets from 1.5 levels above to half a level below the starting cut's
  // mean depth, so the cut stays near n nodes while the turning light moves it.
  double depth = 0;
  for (const NodeId c : cut.nodes()) depth += h->arrays().depth[c];
  depth /= static_cast<double>(cut.size());
  const double deepest = h->level_count() - 1;
  strategies::BucketStrategy s;
  s.set_param("min_depth", std::max(0.0, (depth - 1.5) / deepest));
  s.set_param("max_depth", std::min(1.0, (depth + 0.5) / deepest));
  s.set_param("ambient", 0.0);
  s.reset(*h);
  time_evolving(state, *h, s, cut, [&](std::uint64_t i) {
    ViewSnapshot v = orbit(*h, 0.0f, i);  // the light turns
    const float a = 0.05f * static_cast<float>(i);
    v.light_dir = glm::normalize(glm::vec3(std::cos(a), 0.5f, std::sin(a)));
    return v;
  });
}

void BM_Recursive(benchmark::State& state) {
  const auto h = model(static_cast<int>(state.range(0)));
  if (!h) return state.SkipWithError("../shared/assets/dragon_vrip_normals.ply is absent");
  const auto n = static_cast<std::size_t>(state.range(1));
  if (n > h->leaf_count()) return state.SkipWithError("cut larger than the model");
  strategies::RecursiveStrategy s;
  s.reset(*h);
  std::vector<NodeId> list;
  std::vector<QueryRequest> queries;
  TreeCut unused;
  const ViewSnapshot view = orbit(*h, 0.0f, 0);
  const auto run = [&](const ViewSnapshot& v) {
    list.clear();
    IterationOutput out;
    out.cut = &unused;
    out.nodes = &list;
    out.queries = &queries;
    s.iterate(IterationInput{*h, v}, out);
    return out.result;
  };
  // Find the size threshold that gives about n cut nodes (bisection in log space).
  double lo = 1e-4, hi = 1e4;
  for (int i = 0; i < 40; ++i) {
    const double mid = std::sqrt(lo * hi);
    s.set_param("min_size", mid);
    (run(view).cut_size > n ? lo : hi) = mid;
  }
  s.set_param("min_size", hi);
  Timing t;
  for (auto _ : state) {
    const ViewSnapshot v = orbit(*h, 0.001f * static_cast<float>(t.iterations % 64), t.iterations);
    IterationResult r;
    const double ns = timed([&] { r = run(v); });
    state.SetIterationTime(ns * 1e-9);
    t.add(ns, r);
  }
  report(state, t);
}

void sizes(benchmark::internal::Benchmark* b) {
  for (int m : {0, 1}) {
    for (long n : {10'000L, 30'000L, 100'000L, 300'000L, 1'000'000L, 2'000'000L}) {
      if (m == 0 && n > 400'000) continue;  // the dragon has 437,645 points
      b->Args({m, n});
    }
  }
  b->ArgNames({"model", "cut"})->UseManualTime()->Unit(benchmark::kMillisecond);
}

BENCHMARK(BM_Optimization)->Apply(sizes);
BENCHMARK(BM_Bucket)->Apply(sizes);
BENCHMARK(BM_Recursive)->Apply(sizes);

}  // namespace
}  // namespace treecut::bench

BENCHMARK_MAIN();
