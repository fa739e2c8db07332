// treecut bench build: PLY (or generated) -> ready hierarchy, timed per stage.
// Every repetition runs in a child process, so each one starts cold and its
// peak resident memory (ru_maxrss from wait4) belongs to that build alone.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "commands.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/generate.hpp"
#include "treecut/model_io.hpp"

namespace treecut::cli {

namespace {

struct Sample {
  double read = 0, attributes = 0, build = 0, total = 0;
  std::uint64_t points = 0, nodes = 0;
  std::uint64_t peak_bytes = 0;
  int status = 0;
};

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// "gen:KIND:POINTS", POINTS a whole number in [1, 2^31] as for `gen -n`;
// anything else is an InputError naming the spec.
std::pair<ModelKind, std::uint64_t> parse_gen_spec(const std::string& spec) {
  const auto colon = spec.find(':', 4);
  if (colon == std::string::npos) throw InputError(spec + ": expected gen:KIND:POINTS");
  const ModelKind kind = parse_model_kind(spec.substr(4, colon - 4));
  const std::string_view digits = std::string_view(spec).substr(colon + 1);
  std::uint64_t n = 0;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
  if (ec != std::errc() || ptr != digits.data() + digits.size() || n < 1 || n > (1ull << 31))
    throw InputError(spec + ": POINTS must be a whole number from 1 to 2147483648");
  return {kind, n};
}

// "gen:KIND:N" builds a generated model in memory; anything else is a PLY path.
Sample run_once(const std::string& spec, unsigned threads) {
  Sample s;
  if (spec.rfind("gen:", 0) == 0) {
    const auto [kind, n] = parse_gen_spec(spec);
    PointSet ps = generate_model(kind, n, 1);
    double t0 = now_seconds();
    complete_attributes(ps);
    s.attributes = now_seconds() - t0;
    t0 = now_seconds();
    BuildOptions b;
    b.threads = threads;
    const Hierarchy h = build_hierarchy(std::move(ps), b);
    s.build = now_seconds() - t0;
    s.points = h.leaf_count();
    s.nodes = h.node_count();
  } else {
    OpenOptions o;
    o.use_cache = false;
    o.build.threads = threads;
    const OpenedModel m = open_model(spec, o);
    s.read = m.read_seconds, s.attributes = m.attribute_seconds, s.build = m.build_seconds;
    s.points = m.hierarchy.leaf_count();
    s.nodes = m.hierarchy.node_count();
  }
  s.total = s.read + s.attributes + s.build;
  return s;
}

// The child's report on the pipe: a Sample, or the message of what failed.
// Only the parent prints, so a failed run is one line and the exit code
// follows the child's (2 for bad input such as a malformed PLY, 1 otherwise).
struct ChildReport {
  Sample sample;
  char message[1024] = {};
};

Sample run_in_child(const std::string& spec, unsigned threads) {
  int fds[2];
  if (pipe(fds) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid < 0) {
    const int error = errno;
    close(fds[0]);
    close(fds[1]);
    throw std::runtime_error(std::string("fork: ") + std::strerror(error));
  }
  if (pid == 0) {
    close(fds[0]);
    auto report = std::make_unique<ChildReport>();
    int code = 0;
    try {
      report->sample = run_once(spec, threads);
    } catch (const InputError& e) {
      std::snprintf(report->message, sizeof report->message, "%s", e.what());
      code = 2;
    } catch (const std::exception& e) {
      std::snprintf(report->message, sizeof report->message, "%s", e.what());
      code = 1;
    }
    const ssize_t w = write(fds[1], report.get(), sizeof *report);
    _exit(w == static_cast<ssize_t>(sizeof *report) ? code : 1);
  }
  close(fds[1]);
  auto report = std::make_unique<ChildReport>();
  std::size_t got = 0;
  while (got < sizeof *report) {
    const ssize_t r =
        read(fds[0], reinterpret_cast<char*>(report.get()) + got, sizeof *report - got);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;
    got += static_cast<std::size_t>(r);
  }
  close(fds[0]);
  int status = 0;
  struct rusage ru {};
  while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
  }
  report->message[sizeof report->message - 1] = '\0';
  const bool complete = got == sizeof *report;
  if (WIFEXITED(status) && WEXITSTATUS(status) == 2 && complete) throw InputError(report->message);
  if (WIFSIGNALED(status)) {
    throw std::runtime_error(spec + ": benchmark run killed by signal " +
                             std::to_string(WTERMSIG(status)) + " (" + strsignal(WTERMSIG(status)) +
                             ")");
  }
  if (!complete || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw std::runtime_error(complete && report->message[0] != '\0'
                                 ? std::string(report->message)
                                 : spec + ": benchmark run failed");
  }
  Sample s = report->sample;
  s.peak_bytes = static_cast<std::uint64_t>(ru.ru_maxrss) * 1024;  // Linux reports KiB
  return s;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

void add_bench_commands(CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "Benchmarks that print tables for the README");
  bench->require_subcommand(1);

  struct BuildArgs {
    std::vector<std::string> models;
    int repeat = 5;
    unsigned threads = 0;
  };
  auto args = std::make_shared<BuildArgs>();
  auto* build = bench->add_subcommand("build",
                                      "PLY -> ready hierarchy (read, normals/radii/curvature, "
                                      "build): median wall time and peak memory");
  build
      ->add_option("MODELS", args->models,
                   "PLY files, or gen:KIND:POINTS for an in-memory generated model")
      ->required();
  build->add_option("-r,--repeat", args->repeat, "Repetitions per model (median reported)")
      ->check(CLI::Range(1, 100));
  build->add_option("-t,--threads", args->threads, "Worker threads (0 = all)");
  build->callback([args] {
    // Every input is checked before the first run: a FIFO or a folder is
    // refused at once (a child would block on it), a bad gen: spec too.
    for (const auto& model : args->models) {
      if (model.rfind("gen:", 0) == 0) {
        (void)parse_gen_spec(model);
      } else {
        require_regular_file(model);
      }
    }
    bool header = false;
    for (const auto& model : args->models) {
      std::vector<double> read, attr, hier, total, peak;
      Sample last;
      for (int i = 0; i < args->repeat; ++i) {
        last = run_in_child(model, args->threads);
        read.push_back(last.read), attr.push_back(last.attributes), hier.push_back(last.build);
        total.push_back(last.total), peak.push_back(static_cast<double>(last.peak_bytes));
      }
      const double pk = median(peak);
      // The header follows the first successful model: a malformed first PLY
      // prints one line (its error) and nothing else.
      if (!header) {
        std::printf(
            "| model | points | nodes | read s | attributes s | hierarchy s | total s (median of "
            "%d) | peak MiB | peak B/point |\n",
            args->repeat);
        std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        header = true;
      }
      std::printf("| %s | %llu | %llu | %.3f | %.3f | %.3f | %.3f | %.0f | %.1f |\n",
                  std::filesystem::path(model).filename().string().c_str(),
                  static_cast<unsigned long long>(last.points),
                  static_cast<unsigned long long>(last.nodes), median(read), median(attr),
                  median(hier), median(total), pk / (1024.0 * 1024.0),
                  pk / static_cast<double>(std::max<std::uint64_t>(last.points, 1)));
      std::fflush(stdout);
    }
  });
}

}  // namespace treecut::cli
