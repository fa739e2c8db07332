// treecut strategies [--plugin PATH]...: the registered LOD strategies with
// their parameters, built-in and from plugins.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "option_checks.hpp"
#include "treecut/registry.hpp"
#include "treecut/strategies/builtin.hpp"

namespace treecut::cli {
namespace {

void print_strategies(const StrategyRegistry& registry) {
  for (const StrategyInfo& info : registry.list()) {
    std::printf("%s  (%s)\n  %s\n", info.name.c_str(), info.origin.c_str(),
                info.description.c_str());
    for (const ParamSpec& p : info.params) {
      std::printf("    %-18s %-8g [%g, %g]%s  %s\n", p.name.c_str(), p.default_value, p.min_value,
                  p.max_value, p.integer ? " integer" : "", p.description.c_str());
    }
  }
}

}  // namespace

void add_strategy_commands(CLI::App& app) {
  auto plugins = std::make_shared<std::vector<std::string>>();
  CLI::App* cmd = app.add_subcommand(
      "strategies", "List the LOD strategies and their parameters (plugins included)");
  cmd->add_option("--plugin", *plugins,
                  "Load a strategy plugin (shared library exporting treecut_plugin_register); "
                  "repeatable")
      ->check(non_empty_path());
  cmd->callback([plugins] {
    StrategyRegistry registry = strategies::builtin_registry();
    for (const std::string& path : *plugins) registry.load_plugin(path);  // InputError -> exit 2
    print_strategies(registry);
  });
}

}  // namespace treecut::cli
