// treecut bench scene: the measurements of issue 13's "Benchmarks" on a scene
// and its walkthrough (docs/many-objects.md, "Measured: accuracy, PSNR and
// frame time on the city block"): the `budget` strategy's culling accuracy
// against the renderer's exact ObjectId reference, the points it gives to the
// objects that reference sees, the luma PSNR against full detail and the draw
// time, each with culling on and off at the same budget.
#pragma once

#include <CLI/CLI.hpp>

namespace treecut::cli {

/// Adds `bench scene` to the `bench` group.
void add_bench_scene_command(CLI::App& bench);

}  // namespace treecut::cli
