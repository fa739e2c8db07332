// Render-thread cost per frame of the wait/process protocol ("Parallel
// TreeCut Manipulation", figure 5): poll() with and without an exchange, for
// cuts of 10 thousand and 1 million nodes, against a Feedback Stage thread
// that publishes a new cut every iteration. The exchange swaps buffer
// indices, so its cost must not depend on the cut size. BM_PollExchange runs
// the stage on its thread (a request then wakes it: a futex system call);
// BM_PollExchangeProtocol steps it on the benchmark thread between frames,
// which measures the protocol without a second core. BM_EmptyTimedRegion is
// the noise floor: what the machine adds to any timed sample.
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

// The q-quantile (0.5 = median, 1 = max) of `v`, reordering it.
double quantile(std::vector<double>& v, double q) {
  if (v.empty()) return 0.0;
  const auto i =
      std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(i), v.end());
  return v[i];
}

void report(benchmark::State& state, Samples& s, std::size_t cut) {
  state.counters["exchanges"] = static_cast<double>(s.exchange_frames.size());
  state.counters["xchg_median_ns"] = quantile(s.exchange_frames, 0.5);
  state.counters["xchg_p999_ns"] = quantile(s.exchange_frames, 0.999);
  state.counters["xchg_max_ns"] = quantile(s.exchange_frames, 1.0);
  state.counters["frame_median_ns"] = quantile(s.all, 0.5);
  state.counters["frame_max_ns"] = quantile(s.all, 1.0);
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
  const auto h = generated(tools::ModelKind::Terrain, 1'500'000);
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
  const auto h = generated(tools::ModelKind::Terrain, 1'500'000);
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

// The noise floor of the measurement: the same timed region with nothing or
// a fixed ~0.2 us of arithmetic in it, sampled as often as the frames above.
// Its maximum is what interrupts and the hypervisor add to any sample on this
// machine; a poll maximum near it is not the protocol's.
void BM_EmptyTimedRegion(benchmark::State& state) {
  Samples s;
  s.all.reserve(1 << 16);
  s.exchange_frames.reserve(1 << 16);
  volatile std::uint64_t sink = 0;
  const auto work = static_cast<int>(state.range(0));
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < work; ++i) sink = sink + static_cast<std::uint64_t>(i);
    const double ns = since_ns(t0);
    state.SetIterationTime(ns * 1e-9);
    s.all.push_back(ns);
    s.exchange_frames.push_back(ns);
    for (int i = 0; i < 20000; ++i) sink = sink + static_cast<std::uint64_t>(i);  // a frame's work
  }
  report(state, s, 0);
}

// 20,000 frames per run, each timed by hand.
void frames(benchmark::internal::Benchmark* b) {
  b->UseManualTime()->Iterations(20000)->Unit(benchmark::kNanosecond);
}

BENCHMARK(BM_EmptyTimedRegion)->Arg(0)->Arg(100)->ArgName("work")->Apply(frames);
BENCHMARK(BM_PollExchangeProtocol)->Arg(10'000)->Arg(1'000'000)->ArgName("cut")->Apply(frames);
BENCHMARK(BM_PollExchange)->Arg(10'000)->Arg(1'000'000)->ArgName("cut")->Apply(frames);

}  // namespace
}  // namespace treecut::bench

BENCHMARK_MAIN();
