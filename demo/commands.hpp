// Sub-command groups of the `treecut` program. Each group lives in its own
// file and adds its sub-commands to the app; main() only dispatches.
//
// Exit codes: 0 ok, 1 runtime failure, 2 bad input or usage. A command throws
// treecut::InputError for bad input; main() turns exceptions into codes.
#pragma once

#include <CLI/CLI.hpp>

namespace treecut::cli {

void add_model_commands(CLI::App& app);     // build, info, then gen (model_commands.cpp)
void add_gen_command(CLI::App& app);        // gen (gen_command.cpp)
void add_export_command(CLI::App& app);     // export (export_command.cpp)
void add_cache_command(CLI::App& app);      // cache (cache_command.cpp)
void add_strategy_commands(CLI::App& app);  // strategies (strategy_commands.cpp)
void add_render_commands(CLI::App& app);    // render, view (render_commands.cpp)
void add_bench_commands(CLI::App& app);     // bench (bench_commands.cpp)

}  // namespace treecut::cli
