// treecut: build, inspect and render point-splat hierarchies.
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "commands.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace {

// The command the parse reached: "treecut", "treecut render", "treecut bench build".
struct Reached {
  const CLI::App* app;
  std::string path;
};

std::vector<Reached> reached_commands(const CLI::App& app) {
  std::vector<Reached> chain{{&app, "treecut"}};
  for (;;) {
    const auto subs = chain.back().app->get_subcommands();
    if (subs.empty()) break;
    chain.push_back({subs.front(), chain.back().path + " " + subs.front()->get_name()});
  }
  return chain;
}

std::string command_list(const CLI::App& app) {
  std::string out;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    out += (out.empty() ? "" : ", ") + sub->get_name();
  }
  return out;
}

// One line that names the real problem. CLI11's own text is two lines and,
// for an unknown command, says "A subcommand is required": the unknown word
// is left over in the level that wanted a subcommand, so it is looked up there.
std::string usage_message(const CLI::App& app, const CLI::ParseError& e) {
  const std::vector<Reached> chain = reached_commands(app);
  const Reached& last = chain.back();
  // The first level with words it did not take (an unknown option goes to
  // the level it was written at).
  for (const Reached& level : chain) {
    const std::vector<std::string> left = level.app->remaining(false);
    if (left.empty()) continue;
    const std::string word = left.front();
    const std::string shown = treecut::printable_excerpt(word, 64);
    const std::string see = " (see " + level.path + " --help)";
    if (word.size() > 1 && word[0] == '-') {
      return level.path + ": unknown option '" + shown.substr(0, shown.find('=')) + "'" + see;
    }
    if (level.app->get_require_subcommand_min() > 0 && level.app->get_subcommands().empty()) {
      return level.path + ": unknown command '" + shown + "'" + see;
    }
    return level.path + ": unexpected argument '" + shown + "'" + see;
  }
  if (dynamic_cast<const CLI::RequiredError*>(&e) != nullptr &&
      last.app->get_require_subcommand_min() > 0 && last.app->get_subcommands().empty()) {
    return last.path + ": no command given; one of " + command_list(*last.app) + " (see " +
           last.path + " --help)";
  }
  std::string what = e.what();
  for (char& c : what) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return last.path + ": " + what + " (see " + last.path + " --help)";
}

// `--up -y`: a negative axis is a value, not an option (CLI11 would take
// "-y" for a flag and say --up has no value). Written "--up=-y" instead.
std::vector<std::string> joined_axis_values(int argc, char** argv) {
  std::vector<std::string> out(argv, argv + argc);
  for (std::size_t i = 1; i + 1 < out.size(); ++i) {
    const std::string& next = out[i + 1];
    if (out[i] == "--up" && (next == "-x" || next == "-y" || next == "-z")) {
      out[i] = "--up=" + next;
      out.erase(out.begin() + static_cast<std::ptrdiff_t>(i + 1));
    }
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"treecut: multithreaded point-splat level of detail", "treecut"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Show help for every sub-command");
  treecut::cli::add_model_commands(app);
  treecut::cli::add_export_command(app);
  treecut::cli::add_cache_command(app);
  treecut::cli::add_strategy_commands(app);
  treecut::cli::add_render_commands(app);
  treecut::cli::add_bench_commands(app);
  std::vector<std::string> args = joined_axis_values(argc, argv);
  std::vector<char*> pointers;
  for (std::string& a : args) pointers.push_back(a.data());
  try {
    app.parse(static_cast<int>(pointers.size()), pointers.data());
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "%s\n", treecut::one_line(usage_message(app, e)).c_str());
    return 2;
  } catch (const treecut::InputError& e) {
    // one_line(): whatever a message quotes of the user's (a file name, a
    // token), it stays one line and sends the terminal no control sequence.
    std::fprintf(stderr, "treecut: %s\n", treecut::one_line(e.what()).c_str());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr,
                 "treecut: error: out of memory (the model or the options ask for more than this "
                 "machine gives)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "treecut: error: %s\n", treecut::one_line(e.what()).c_str());
    return 1;
  }
  // What a command printed must have reached its reader: `treecut info m.ply
  // > /dev/full` is a failure, not a silent success.
  errno = 0;
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0) {
    std::fprintf(stderr, "treecut: error: standard output: %s\n",
                 std::strerror(errno != 0 ? errno : EIO));
    return 1;
  }
  return 0;
}
