// treecut: build, inspect and render point-splat hierarchies.
#include <cstdio>
#include <exception>

#include "commands.hpp"
#include "treecut/error.hpp"

int main(int argc, char** argv) {
  CLI::App app{"treecut: multithreaded point-splat level of detail"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Show help for every sub-command");
  treecut::cli::add_model_commands(app);
  treecut::cli::add_strategy_commands(app);
  treecut::cli::add_render_commands(app);
  treecut::cli::add_bench_commands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  } catch (const treecut::InputError& e) {
    std::fprintf(stderr, "treecut: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "treecut: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
