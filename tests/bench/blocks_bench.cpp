// HLOD block build time (strategies/include/treecut/culling/hlod_blocks.hpp):
// decides whether blocks must be cached with the hierarchy or can be rebuilt
// at load. The dragon from ../shared/assets and a generated terrain of
// TREECUT_BENCH_POINTS (default 20 million) points; block_size 1000 (the
// default) and 250. Process CPU time and wall time (the build is parallel).
//
//   build/NAME/tests/bench/blocks_bench --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include "bench_models.hpp"
#include "treecut/culling/hlod_blocks.hpp"

namespace {

using treecut::Hierarchy;
using treecut::culling::HlodBlocks;

void run(benchmark::State& state, const Hierarchy& h) {
  const auto block_size = static_cast<std::uint32_t>(state.range(0));
  std::uint32_t blocks = 0, leaf_blocks = 0;
  for (auto _ : state) {
    HlodBlocks b = HlodBlocks::build(h, block_size);
    blocks = b.block_count();
    leaf_blocks = b.leaf_block_count();
    benchmark::DoNotOptimize(b);
  }
  state.counters["blocks"] = blocks;
  state.counters["leaf_blocks"] = leaf_blocks;
  state.counters["leaves"] = h.leaf_count();
}

void BM_BlocksDragon(benchmark::State& state) {
  static const auto h = treecut::bench::dragon();
  if (!h) {
    state.SkipWithError("../shared/assets/dragon_vrip_normals.ply absent");
    return;
  }
  run(state, *h);
}

void BM_BlocksTerrain(benchmark::State& state) {
  static const auto h = treecut::bench::generated(treecut::tools::ModelKind::Terrain,
                                                  treecut::bench::large_cloud_points());
  run(state, *h);
}

BENCHMARK(BM_BlocksDragon)
    ->Arg(1000)
    ->Arg(250)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime();
BENCHMARK(BM_BlocksTerrain)
    ->Arg(1000)
    ->Arg(250)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
