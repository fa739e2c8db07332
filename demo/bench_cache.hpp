// `treecut bench cache`: what a model's cache costs on disk and in time
// (issue 44, the paged cache): bytes a point, saving and opening it.
#pragma once

#include <CLI/CLI.hpp>

namespace treecut::cli {

void add_bench_cache_command(CLI::App& bench);

}  // namespace treecut::cli
