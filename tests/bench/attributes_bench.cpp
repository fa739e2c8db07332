// Normals, radii and curvature of a point cloud (complete_attributes: the k
// nearest neighbours in a grid, a PCA each): the stage that holds most of a
// survey's build time (issue 44). One tile of `gen survey` of
// TREECUT_BENCH_POINTS points (default 1 million) at 8 points/m^2, and the
// Stanford dragon's points; k = 12 (the default) and 24. Wall and process
// CPU time (the stage runs on every core).
//
//   build/NAME/tests/bench/attributes_bench --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>

#include "test_support.hpp"
#include "treecut/attributes.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/survey.hpp"

namespace {

using treecut::PointSet;

const PointSet& survey() {
  static const PointSet ps = [] {
    const char* env = std::getenv("TREECUT_BENCH_POINTS");
    const double points = env ? std::strtod(env, nullptr) : 1e6;
    treecut::tools::SurveyOptions o;
    o.width = o.height = std::sqrt(points / o.density);
    o.tile = 100000.0;  // one tile
    return treecut::tools::generate_survey_tile(o, treecut::tools::survey_tiles(o).front());
  }();
  return ps;
}

void run(benchmark::State& state, const PointSet& source) {
  treecut::AttributeOptions options;
  options.k = static_cast<int>(state.range(0));
  options.recompute_normals = options.recompute_radii = true;
  for (auto _ : state) {
    state.PauseTiming();
    PointSet ps;
    ps.positions = source.positions;
    ps.frame = source.frame;
    state.ResumeTiming();
    treecut::complete_attributes(ps, options);
    benchmark::DoNotOptimize(ps.normals.data());
  }
  state.counters["points"] = static_cast<double>(source.size());
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(source.size()),
                                                  benchmark::Counter::kIsIterationInvariantRate);
}

void BM_Survey(benchmark::State& state) {
  run(state, survey());
}

void BM_Dragon(benchmark::State& state) {
  static const PointSet dragon = [] {
    PointSet ps;
    if (const auto ply = treecut::test::shared_asset("dragon_vrip.ply"))
      ps.positions = treecut::load_ply(*ply).positions;
    return ps;
  }();
  if (dragon.size() == 0) {
    state.SkipWithError("../shared/assets/dragon_vrip.ply is absent");
    return;
  }
  run(state, dragon);
}

}  // namespace

BENCHMARK(BM_Survey)
    ->Arg(12)
    ->Arg(24)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();
BENCHMARK(BM_Dragon)
    ->Arg(12)
    ->Arg(24)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();
BENCHMARK_MAIN();
