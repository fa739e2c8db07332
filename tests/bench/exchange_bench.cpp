// Render-thread cost per frame of the wait/process protocol ("Parallel
// TreeCut Manipulation", figure 5): poll() with and without an exchange, for
// cuts of 10 thousand and 1 million nodes, against a Feedback Stage thread
// that publishes a new cut every iteration. The exchange swaps buffer
// indices, so its cost must not depend on the cut size. BM_PollExchange runs
// the stage on its thread (a request then wakes it: a futex system call);
// BM_PollExchangeProtocol steps it on the benchmark thread between frames,
// which measures the protocol without the operating system's wake-up.
//
//   exchange_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <vector>

#include "bench_models.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"

namespace treecut::bench {
namespace {

// Never converges and keeps the cut size: refines a random node, and in the
// next iteration coarsens it back, so every iteration publishes a new list.
class ChurnStrategy final : public Strategy {
 public:
  ChurnStrategy() : Strategy({}) {}
  [[nodiscard]] std::string_view name() const override { return "churn"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override { last_ = kNoNode; }
  void iterate(const IterationInput& in, IterationOutput& out) override {
    TreeCut& cut = *out.cut;
    if (last_ != kNoNode && cut.coarsen(in.hierarchy, last_)) {
      last_ = kNoNode;
      return;
    }
    for (int tries = 0; tries < 64; ++tries) {
      const NodeId n = cut.nodes()[rng_() % cut.size()];
      if (cut.refine(in.hierarchy, n)) {
        last_ = n;
        return;
      }
    }
  }

 private:
  std::mt19937 rng_{1};
  NodeId last_ = kNoNode;
};

struct Samples {
  std::vector<double> all, exchange_frames;
};

void report(benchmark::State& state, Samples& s, std::size_t cut) {
  const auto median = [](std::vector<double>& v) {
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const auto max = [](const std::vector<double>& v) {
    return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
  };
  state.counters["exchanges"] = static_cast<double>(s.exchange_frames.size());
  state.counters["xchg_median_ns"] = median(s.exchange_frames);
  state.counters["xchg_max_ns"] = max(s.exchange_frames);
  state.counters["frame_median_ns"] = median(s.all);
  state.counters["frame_max_ns"] = max(s.all);
  state.counters["cut"] = static_cast<double>(cut);
}

double since_ns(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
}

// The protocol alone: Launch::Manual, the benchmark thread runs the stage's
// step() outside the timed region, so poll() exchanges and requests without
// having to wake a sleeping thread (no system call).
void BM_PollExchangeProtocol(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto h = generated(ModelKind::Terrain, 1'500'000);
  StageOptions o;
  o.launch = Launch::Manual;
  FeedbackStage stage(Model{h, breadth_first_cut(*h, n)}, std::make_unique<ChurnStrategy>(), o);
  Samples s;
  s.all.reserve(1 << 16);
  s.exchange_frames.reserve(1 << 16);
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const FrameLists f = stage.poll();
    const double ns = since_ns(t0);
    state.SetIterationTime(ns * 1e-9);
    s.all.push_back(ns);
    if (f.exchanged) s.exchange_frames.push_back(ns);
    stage.step();
  }
  report(state, s, stage.front().nodes.size());
}

void BM_PollExchange(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto h = generated(ModelKind::Terrain, 1'500'000);
  FeedbackStage stage(Model{h, breadth_first_cut(*h, n)}, std::make_unique<ChurnStrategy>());
  Samples s;
  s.all.reserve(1 << 16);
  s.exchange_frames.reserve(1 << 16);
  volatile std::uint64_t sink = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const FrameLists f = stage.poll();
    const double ns = since_ns(t0);
    state.SetIterationTime(ns * 1e-9);
    s.all.push_back(ns);
    if (f.exchanged) s.exchange_frames.push_back(ns);
    sink = sink + f.current.nodes.size();
    // The rest of the frame (drawing): some 50 microseconds of work.
    for (int i = 0; i < 20000; ++i) sink = sink + static_cast<std::uint64_t>(i);
  }
  report(state, s, stage.front().nodes.size());
}

BENCHMARK(BM_PollExchangeProtocol)
    ->Arg(10'000)
    ->Arg(1'000'000)
    ->ArgName("cut")
    ->UseManualTime()
    ->Iterations(20000)
    ->Unit(benchmark::kNanosecond);
BENCHMARK(BM_PollExchange)
    ->Arg(10'000)
    ->Arg(1'000'000)
    ->ArgName("cut")
    ->UseManualTime()
    ->Iterations(20000)
    ->Unit(benchmark::kNanosecond);

}  // namespace
}  // namespace treecut::bench

BENCHMARK_MAIN();
