// treecut bench build: PLY (or generated) -> ready hierarchy, timed per stage.
// Every repetition runs in a child process, so each one starts cold and its
// peak resident memory (ru_maxrss from wait4) belongs to that build alone.
// treecut bench occlusion: the occlusion papers' tables on a walkthrough,
// headless (docs/occlusion.md); one function per table.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "bench_cache.hpp"
#include "bench_common.hpp"
#include "bench_hlod.hpp"
#include "bench_scene.hpp"
#include "commands.hpp"
#include "headless_gl.hpp"
#include "option_checks.hpp"
#include "treecut/culling/chc.hpp"
#include "treecut/culling/gpu_latency.hpp"
#include "treecut/culling/hlod_blocks.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/model_io.hpp"
#include "treecut/parallel.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/occlusion_device_gl.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"
#include "viewer.hpp"

namespace treecut::cli {

namespace {

struct Sample {
  double read = 0, attributes = 0, build = 0, total = 0;
  std::uint64_t points = 0, nodes = 0, chunks = 0, lanes = 0;
  std::uint64_t peak_bytes = 0;
  int status = 0;
};

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// "gen:KIND:POINTS", POINTS a whole number in [1, 2^31] as for `gen -n`;
// anything else is an InputError naming the spec.
std::pair<tools::ModelKind, std::uint64_t> parse_gen_spec(const std::string& spec) {
  const auto colon = spec.find(':', 4);
  if (colon == std::string::npos) throw InputError(spec + ": expected gen:KIND:POINTS");
  const tools::ModelKind kind = tools::parse_model_kind(spec.substr(4, colon - 4));
  const std::string_view digits = std::string_view(spec).substr(colon + 1);
  std::uint64_t n = 0;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
  if (ec != std::errc() || ptr != digits.data() + digits.size() || n < 1 || n > (1ull << 31))
    throw InputError(spec + ": POINTS must be a whole number from 1 to 2147483648");
  return {kind, n};
}

// "gen:KIND:N" builds a generated model in memory; anything else is a PLY
// path. With MEMORY, the file's build has that budget and a cache in a
// folder of its own (a build past the budget goes in chunks into it),
// removed after.
Sample run_once(const std::string& spec, unsigned threads, std::uint64_t memory) {
  Sample s;
  if (spec.rfind("gen:", 0) == 0) {
    const auto [kind, n] = parse_gen_spec(spec);
    PointSet ps = tools::generate_model(kind, n, 1);
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
    o.use_cache = memory != 0;
    o.require_cache = o.rebuild = memory != 0;
    o.memory = memory;
    o.need_hierarchy = memory == 0;
    o.build.threads = threads;
    std::optional<ScratchCache> cache;
    if (memory) {
      cache.emplace("build");
      o.cache_path = cache->path;
    }
    const OpenedModel m = open_model(spec, o);
    s.read = m.read_seconds, s.attributes = m.attribute_seconds, s.build = m.build_seconds;
    s.points = m.input_points;
    s.nodes = m.hierarchy.empty() ? m.chunked.nodes : m.hierarchy.node_count();
    s.chunks = m.chunked.chunks;
    s.lanes = m.chunked.lanes;
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

Sample run_in_child(const std::string& spec, unsigned threads, std::uint64_t memory) {
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
      report->sample = run_once(spec, threads, memory);
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

double mean(const std::vector<double>& v) {
  double sum = 0.0;
  for (const double x : v) sum += x;
  return v.empty() ? 0.0 : sum / static_cast<double>(v.size());
}

// ---------------------------------------------------------------------------
// bench occlusion: CHC (Bittner et al. 2004) and its baselines on one path.

struct OcclusionArgs {
  std::string scene;
  std::string gl = "auto";  // headless back end (--gl)
  std::string path;
  double fps = 10.0;
  int frames = 0;  // > 0: that many frames evenly spaced instead of every 1 / fps s
  // The part of the walk measured, in path seconds (to < 0: its end): a
  // stretch at the walk's own frame rate in the time a full run would not fit.
  double from = 0.0;
  double to = -1.0;
  bool no_chc = false;  // the HLOD table alone (half the frames drawn)
  int width = 1280;
  int height = 720;
  std::uint32_t block_size = culling::kDefaultBlockSize;
  // The tree of blocks (HlodBlocks::build): 2 binary (the paper's kD-tree), 4
  // the hierarchy's; compare_fan_out adds the CHC table's VFC, S&W, CHC and
  // Ideal rows on a second tree, frames interleaved with the first.
  unsigned fan_out = culling::kBinaryFanOut;
  unsigned compare_fan_out = 0;
  bool flush_row = false;
  bool probe_row = false;  // diagnostics: Ideal with a box query before every block it draws
  // The HLOD table (bench_hlod.hpp): tau, PSNR frames, per-frame CSV folder.
  float hlod_tau = 1.0f;
  int psnr_frames = 20;
  std::string csv_dir;
  bool no_hlod = false;
  std::uint32_t poll_every = 0;  // > 0: a CHC row polling every that many blocks
  // The GPU-latency model (culling/gpu_latency.hpp): every method's device
  // answers this late; the stage strategy's executor too (in frames).
  std::string latency = "0";
};

// One method of the CHC table and what each frame of the path did.
struct ChcRun {
  std::string method;
  culling::ChcOptions options;
  std::vector<culling::ChcFrameStats> frames;
  bool flush_per_block = false;  // diagnostics: GlOcclusionDevice::set_flush_after_draw
  unsigned tree = 0;             // 0: the --block-fan-out tree, 1: the --compare-fan-out one
};

// The mean over frames f of base[f] / run[f], the frames where both times are
// positive (the paper's table 1 speed-up: "averages over all frames
// (including the speedup)"); 0 for none.
double mean_per_frame_speedup(const std::vector<double>& base, const std::vector<double>& run) {
  double sum = 0.0;
  int count = 0;
  for (std::size_t f = 0; f < std::min(base.size(), run.size()); ++f) {
    if (base[f] <= 0.0 || run[f] <= 0.0) continue;
    sum += base[f] / run[f];
    ++count;
  }
  return count > 0 ? sum / count : 0.0;
}

// The paper's table 1 (+ its table 2 rows): means over the frames of the path.
void print_chc_table(const std::vector<ChcRun>& runs) {
  const auto column = [](const ChcRun& r, auto field) {
    std::vector<double> v;
    for (const auto& f : r.frames) v.push_back(static_cast<double>(field(f)));
    return v;
  };
  const auto frame_ms = [](const culling::ChcFrameStats& f) { return f.frame_ms; };
  // Speed-ups against the VFC row of the same tree of blocks, whose frames
  // are the same cameras in the same order.
  std::vector<double> vfc_ms[2];
  for (const ChcRun& r : runs) {
    if (r.options.mode == culling::OcclusionMode::Vfc) vfc_ms[r.tree] = column(r, frame_ms);
  }
  std::printf(
      "| method | t_av | n_vp | queries | blocking reads | wait ms | of it, end-of-frame drain ms "
      "| leaf blocks drawn | splats rendered | frame ms (mean) | frame ms (median) | speed-up vs "
      "VFC (ratio of means) | speed-up vs VFC (mean per frame, the paper's) | delayed blocks |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const ChcRun& r : runs) {
    const bool queries = r.options.mode == culling::OcclusionMode::StopAndWait ||
                         r.options.mode == culling::OcclusionMode::Chc ||
                         r.options.mode == culling::OcclusionMode::ChcPlusPlus ||
                         r.options.ideal_probe_queries;
    const double ms = mean(column(r, frame_ms));
    char q[32] = "---", b[32] = "---", w[32] = "---", dr[32] = "---", late[32] = "---";
    if (queries) {
      std::snprintf(q, sizeof q, "%.1f", mean(column(r, [](const auto& f) { return f.queries; })));
      std::snprintf(b, sizeof b, "%.1f",
                    mean(column(r, [](const auto& f) { return f.blocking_reads; })));
      std::snprintf(w, sizeof w, "%.3f", mean(column(r, [](const auto& f) { return f.wait_ms; })));
      std::snprintf(dr, sizeof dr, "%.3f",
                    mean(column(r, [](const auto& f) { return f.drain_wait_ms; })));
    }
    if (r.options.mode == culling::OcclusionMode::ChcPlusPlus) {
      std::snprintf(late, sizeof late, "%.2f",
                    mean(column(r, [](const auto& f) { return f.delayed_blocks; })));
    }
    std::printf(
        "| %s | %u | %llu | %s | %s | %s | %s | %.1f | %.0f | %.2f | %.2f | %.2f | %.2f | %s |\n",
        r.method.c_str(), r.options.assume_visible_frames,
        static_cast<unsigned long long>(r.options.min_visible_samples), q, b, w, dr,
        mean(column(r, [](const auto& f) { return f.blocks_drawn; })),
        mean(column(r, [](const auto& f) { return f.splats_drawn; })), ms,
        median(column(r, frame_ms)), ms > 0.0 ? mean(vfc_ms[r.tree]) / ms : 0.0,
        mean_per_frame_speedup(vfc_ms[r.tree], column(r, frame_ms)), late);
  }
  std::fflush(stdout);
}

// The part of the walk a run measures: the path, the end of the part, its
// length in path seconds and the frames taken over it.
struct OcclusionWalk {
  splat::CameraPath path;
  double to = 0.0;
  double span = 0.0;
  int frames = 0;
  culling::GpuLatency latency;
};

// Every option of bench occlusion checked before any work (exit 2 with one
// line), and the frames of the walk.
OcclusionWalk check_occlusion_args(const OcclusionArgs& a) {
  if (a.frames < 0) throw InputError("--frames must not be negative");
  if (!(a.fps > 0.0) || a.fps > 1000.0) throw InputError("--fps must be in (0, 1000]");
  if (a.block_size < 1) throw InputError("--block-size must be at least 1");
  if (a.fan_out != 2 && a.fan_out != 4) throw InputError("--block-fan-out must be 2 or 4");
  if (a.compare_fan_out != 0 &&
      (a.compare_fan_out == a.fan_out || (a.compare_fan_out != 2 && a.compare_fan_out != 4))) {
    throw InputError("--compare-fan-out must be the other of 2 and 4");
  }
  culling::GpuLatency latency;
  try {
    latency = culling::parse_gpu_latency(a.latency);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--latency: ") + e.what());
  }
  OcclusionWalk w{splat::load_camera_path(a.path), 0.0, 0.0, 0, latency};  // exit 2 before any work
  if (!a.no_hlod && !a.csv_dir.empty()) check_hlod_csv(hlod_csv_path(a.csv_dir, a.scene));
  w.to = walk_part_end(w.path, a.path, a.from, a.to);
  if (a.no_chc && a.no_hlod) throw InputError("--no-chc and --no-hlod leave nothing to run");
  // The path at 1 / fps steps (a walk at that frame rate), or `frames` evenly
  // spaced times; the first and last key included.
  w.span = w.to - a.from;
  // In double: a path of 1e300 s at 10 fps is no int (it wrapped negative).
  const double walk_frames = 1.0 + std::floor(w.span * a.fps + 1e-9);
  if (a.frames == 0 && !(walk_frames <= 1e6)) {
    char msg[200];
    std::snprintf(msg, sizeof msg,
                  ": %.6g s of path at %g fps is %.6g frames, more than 1000000; use --frames, "
                  "--fps, --from or --to",
                  w.span, a.fps, walk_frames);
    throw InputError(quoted_name(a.path) + msg);
  }
  w.frames = a.frames > 0 ? a.frames : static_cast<int>(walk_frames);
  return w;
}

// The rows of the CHC table: the paper's six, then the diagnostic rows asked
// for, then (compare) VFC, S&W, CHC and Ideal on the other tree of blocks.
std::vector<ChcRun> chc_runs(const OcclusionArgs& a, bool compare) {
  using culling::OcclusionMode;
  std::vector<ChcRun> runs = {
      {"VFC", {OcclusionMode::Vfc, 0, 0}, {}},
      {"S&W", {OcclusionMode::StopAndWait, 0, 0}, {}},
      {"CHC", {OcclusionMode::Chc, 0, 0}, {}},
      {"Ideal", {OcclusionMode::Ideal, 0, 0}, {}},
      {"CHC", {OcclusionMode::Chc, 2, 0}, {}},
      {"CHC", {OcclusionMode::Chc, 0, 25}, {}},
      // CHC++ (chc_plus_plus.cpp): exact, then with randomized t_av.
      {"CHC++", {OcclusionMode::ChcPlusPlus, 0, 0}, {}},
      {"CHC++", {OcclusionMode::ChcPlusPlus, 4, 0}, {}},
      // ... and never waiting: disocclusions drawn a frame or more late.
      {"CHC++, no wait", {OcclusionMode::ChcPlusPlus, 4, 0, 1, false, 32, false}, {}},
  };
  // Diagnostics: Ideal with a glFlush after every block, the batches CHC's
  // polls cut llvmpipe's work into, without any query or wait.
  if (a.flush_row) {
    runs.push_back({"Ideal, glFlush per block", {OcclusionMode::Ideal, 0, 0}, {}, true});
  }
  if (a.poll_every > 0) {
    runs.push_back({"CHC, poll every " + std::to_string(a.poll_every) + " blocks",
                    {OcclusionMode::Chc, 0, 0, a.poll_every},
                    {}});
  }
  // Diagnostics: Ideal's draws with a box query before each (answers polled
  // as CHC polls them, then ignored): the queries' own cost, draws equal.
  if (a.probe_row) {
    runs.push_back({"Ideal + a box query per block", {OcclusionMode::Ideal, 0, 0, 1, true}, {}});
  }
  if (compare) {
    const std::string tag = ", fan-out " + std::to_string(a.compare_fan_out);
    for (const OcclusionMode m : {OcclusionMode::Vfc, OcclusionMode::StopAndWait,
                                  OcclusionMode::Chc, OcclusionMode::Ideal}) {
      const char* name = m == OcclusionMode::Vfc           ? "VFC"
                         : m == OcclusionMode::StopAndWait ? "S&W"
                         : m == OcclusionMode::Chc         ? "CHC"
                                                           : "Ideal";
      runs.push_back({name + tag, {m, 0, 0}, {}, false, 1});
    }
  }
  return runs;
}

// The frames of every run of the CHC table, into runs[r].frames; `trees`
// and `devices`: the --block-fan-out tree and (compare) the other one.
void measure_chc_runs(std::vector<ChcRun>& runs, std::array<const culling::HlodBlocks*, 2> trees,
                      std::array<splat::GlOcclusionDevice*, 2> devices,
                      const std::vector<splat::Camera>& cameras,
                      const splat::RenderSettings& settings, glm::ivec2 size,
                      culling::GpuLatency latency) {
  using culling::OcclusionMode;
  // Ideal replays, frame by frame, the leaf blocks S&W found visible for the
  // same camera (S&W's frame runs just before).
  std::vector<culling::BlockId> sw_set[2];
  // Each method has its own traversal (its own previous frames), and the
  // methods take turns frame by frame: every method sees the path in order,
  // and a change of the machine's load (other processes on the 2 cores)
  // falls on all of them alike instead of on whichever ran then.
  std::vector<culling::ChcTraversal> traversals;
  // Each method its own latency model: its frames are its own (the methods
  // take turns on one GL device).
  std::vector<culling::LatentOcclusionDevice> latent;
  for (const ChcRun& run : runs) {
    traversals.emplace_back(*trees[run.tree], run.options);
    latent.emplace_back(*devices[run.tree], latency);
  }
  auto frame = [&](std::size_t r, std::size_t f) {
    const ChcRun& run = runs[r];
    splat::GlOcclusionDevice& dev = *devices[run.tree];
    dev.set_flush_after_draw(run.flush_per_block);
    dev.set_view_render_thread(cameras[f], settings);
    if (run.options.mode == OcclusionMode::Ideal) traversals[r].set_ideal_leaves(sw_set[run.tree]);
    const auto stats = traversals[r].frame_render_thread(latent[r], cameras[f].view(size), true);
    if (run.options.mode == OcclusionMode::StopAndWait) sw_set[run.tree] = traversals[r].drawn();
    return stats;
  };
  // One untimed frame at the first camera: the GPU's caches warm, and CHC
  // starts the path with a previous frame as it would in a walk. S&W comes
  // before Ideal in `runs`: Ideal replays the set S&W found for this camera.
  for (std::size_t r = 0; r < runs.size(); ++r) (void)frame(r, 0);
  for (std::size_t f = 0; f < cameras.size(); ++f) {
    for (std::size_t r = 0; r < runs.size(); ++r) runs[r].frames.push_back(frame(r, f));
  }
  // Queries still in flight (CHC++'s carried answers) go back to the pool.
  for (std::size_t r = 0; r < runs.size(); ++r) traversals[r].release_render_thread(latent[r]);
}

void run_bench_occlusion(const OcclusionArgs& a) {
  const OcclusionWalk walk = check_occlusion_args(a);
  const splat::CameraPath& path = walk.path;
  const double span = walk.span;
  const int frames = walk.frames;

  SceneArgs scene_args;
  scene_args.model = a.scene;
  if (!a.scene.empty()) require_regular_file(a.scene);
  const Scene scene = load_scene(scene_args);
  const Hierarchy& h = *scene.hierarchy;
  const double t0 = now_seconds();
  const culling::HlodBlocks blocks = culling::HlodBlocks::build(h, a.block_size, a.fan_out);
  const double block_seconds = now_seconds() - t0;
  const bool compare = a.compare_fan_out != 0 && !a.no_chc;
  const culling::HlodBlocks other =
      compare ? culling::HlodBlocks::build(h, a.block_size, a.compare_fan_out)
              : culling::HlodBlocks();

  const glm::ivec2 size(a.width, a.height);
  const std::unique_ptr<splat::GlContext> context = open_headless(a.gl, a.width, a.height);
  splat::Renderer renderer(h, size);
  splat::GlOcclusionDevice device(renderer, blocks);
  std::unique_ptr<splat::GlOcclusionDevice> other_device;
  if (compare) other_device = std::make_unique<splat::GlOcclusionDevice>(renderer, other);
  splat::RenderSettings settings;  // fast splats: the one-pass mode of in-frame draws

  std::vector<splat::Camera> cameras;
  for (int f = 0; f < frames; ++f) {
    const double t = a.from + (frames == 1 ? 0.0 : span * f / (frames - 1));
    splat::Camera c = path.at(t);
    splat::fit_clip_planes(c, scene.center, scene.radius);
    cameras.push_back(c);
  }
  std::printf(
      "scene     %s: %u points, %u nodes; %u blocks (%u leaf blocks) of <= %u splats, "
      "fan-out %u, built in %.3f s\n",
      scene.label.c_str(), h.leaf_count(), h.node_count(), blocks.block_count(),
      blocks.leaf_block_count(), blocks.block_size(), blocks.fan_out(), block_seconds);
  if (compare) {
    std::printf("compare   fan-out %u: %u blocks (%u leaf blocks)\n", other.fan_out(),
                other.block_count(), other.leaf_block_count());
  }
  std::printf("renderer  %s, %dx%d, fast splats, full detail (leaf blocks)\n",
              renderer_line(*context).c_str(), a.width, a.height);
  std::printf(
      "path      %s: %d frames over %.1f s (%.1f to %.1f s of %.1f); means over the frames "
      "(frame ms: glFinish-ed wall time; wait ms: CPU blocked in query reads)\n",
      a.path.c_str(), frames, span, a.from, walk.to, path.duration());
  std::printf("latency   %s (GPU-latency model: answers no earlier than that after their issue)\n",
              culling::describe(walk.latency).c_str());
  std::fflush(stdout);

  if (!a.no_chc) {
    std::vector<ChcRun> runs = chc_runs(a, compare);
    measure_chc_runs(runs, {&blocks, &other}, {&device, other_device.get()}, cameras, settings,
                     size, walk.latency);
    print_chc_table(runs);
  }
  if (!a.no_hlod) {
    HlodBenchInput hlod;
    hlod.hierarchy = scene.hierarchy;
    hlod.blocks = &blocks;
    hlod.renderer = &renderer;
    hlod.device = &device;
    hlod.cameras = cameras;
    hlod.settings = settings;
    hlod.size = size;
    hlod.tau = a.hlod_tau;
    hlod.psnr_frames = a.psnr_frames;
    hlod.latency = walk.latency;
    if (!a.csv_dir.empty()) hlod.csv = hlod_csv_path(a.csv_dir, a.scene);
    run_hlod_table(hlod);
  }
}

struct BuildArgs {
  std::vector<std::string> models;
  int repeat = 5;
  unsigned threads = 0;
  std::uint64_t memory = 0;  // 0: each build held whole, no cache
};

// bench build: every model built `repeat` times, each in a child process;
// one table row per model.
void run_bench_build(const BuildArgs& args) {
  // Every input is checked before the first run: a FIFO is refused at
  // once (a child would block on it), a bad gen: spec too. A folder is the
  // model of its point files (a survey's tiles).
  for (const auto& model : args.models) {
    std::error_code ec;
    if (model.rfind("gen:", 0) == 0) {
      (void)parse_gen_spec(model);
    } else if (std::filesystem::is_directory(model, ec)) {
      (void)point_files_in(model);
    } else {
      require_regular_file(model);
    }
  }
  bool header = false;
  for (const auto& model : args.models) {
    std::vector<double> read, attr, hier, total, peak;
    Sample last;
    for (int i = 0; i < args.repeat; ++i) {
      last = run_in_child(model, args.threads, args.memory);
      read.push_back(last.read), attr.push_back(last.attributes), hier.push_back(last.build);
      total.push_back(last.total), peak.push_back(static_cast<double>(last.peak_bytes));
    }
    const double pk = median(peak);
    // The header follows the first successful model: a malformed first PLY
    // prints one line (its error) and nothing else.
    if (!header) {
      std::printf(
          "| model | points | nodes | read s | attributes s | hierarchy s | total s (median of "
          "%d) | peak MiB | peak B/point |%s\n",
          args.repeat, args.memory ? " chunks | at once | M points/s a core |" : "");
      std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|%s\n",
                  args.memory ? "---:|---:|---:|" : "");
      header = true;
    }
    // A folder given as "tiles/" by its own name.
    const std::filesystem::path path(model);
    const std::string name = (path.filename().empty() ? path.parent_path() : path).filename();
    std::printf("| %s | %llu | %llu | %.3f | %.3f | %.3f | %.3f | %.0f | %.1f |", name.c_str(),
                static_cast<unsigned long long>(last.points),
                static_cast<unsigned long long>(last.nodes), median(read), median(attr),
                median(hier), median(total), pk / (1024.0 * 1024.0),
                pk / static_cast<double>(std::max<std::uint64_t>(last.points, 1)));
    // The rate over the cores the build had, as issue 44 states its figure.
    const unsigned cores = worker_count(args.threads);
    if (args.memory)
      std::printf(" %llu | %llu | %.2f |", static_cast<unsigned long long>(last.chunks),
                  static_cast<unsigned long long>(last.lanes),
                  double(last.points) / median(total) / 1e6 / cores);
    std::printf("\n");
    std::fflush(stdout);
  }
}

void add_bench_build_command(CLI::App& bench) {
  auto args = std::make_shared<BuildArgs>();
  auto* build =
      bench.add_subcommand("build",
                           "point file -> ready hierarchy (read, normals/radii/curvature, "
                           "build): median wall time and peak memory");
  build
      ->add_option("MODELS", args->models,
                   "Point files (PLY, LAS, PCD, text), folders of them (one model each), or "
                   "gen:KIND:POINTS for an in-memory generated model")
      ->check(non_empty_path())
      ->required();
  build->add_option("-r,--repeat", args->repeat, "Repetitions per model (median reported)")
      ->check(whole_number(1, 100));
  build->add_option("-t,--threads", args->threads, "Worker threads (0 = all)")
      ->check(whole_number(0, 1024));
  add_memory_option(*build, args->memory);
  build->callback([args] { run_bench_build(*args); });
}

void add_bench_occlusion_command(CLI::App& bench) {
  auto occ = std::make_shared<OcclusionArgs>();
  auto* occlusion = bench.add_subcommand(
      "occlusion",
      "Occlusion culling on a walkthrough, headless: the CHC table (VFC, S&W, CHC, Ideal, CHC "
      "t_av=2, CHC n_vp=25; docs/occlusion.md)");
  occlusion->add_option("SCENE", occ->scene, "PLY or .tch (e.g. one made by treecut gen city)")
      ->check(non_empty_path())
      ->required();
  occlusion->add_option("--path", occ->path, "Camera path (assets/paths/*_walk.campath)")
      ->check(non_empty_path())
      ->required();
  occlusion->add_option("--fps", occ->fps, "Frames per second of path time (default 10)")
      ->check(finite_number(0.0, 1000.0));
  occlusion
      ->add_option("--frames", occ->frames,
                   "Frames evenly spaced over the path instead (0: every 1 / fps s)")
      ->check(whole_number(0, 1000000));
  occlusion->add_option("--from", occ->from, "Start of the part of the path measured, seconds")
      ->check(finite_number(0.0, 1e6));
  occlusion->add_option("--to", occ->to, "End of the part of the path measured (default: its end)")
      ->check(finite_number(0.0, 1e6));
  add_gl_option(occlusion, &occ->gl);
  occlusion->add_option("--width", occ->width, "Width in pixels")->check(whole_number(16, 8192));
  occlusion->add_option("--height", occ->height, "Height in pixels")->check(whole_number(16, 8192));
  occlusion->add_option("--block-size", occ->block_size, "HLOD block size (splats per block)")
      ->check(whole_number(1, 0xffffffffu));
  occlusion
      ->add_option("--block-fan-out", occ->fan_out,
                   "Children per interior block: 2 binary (default), 4 the hierarchy's")
      ->check(whole_number(2, 4));
  occlusion
      ->add_option("--compare-fan-out", occ->compare_fan_out,
                   "Add VFC, S&W, CHC and Ideal rows on a tree of this fan-out (the other "
                   "of 2 and 4), frames interleaved")
      ->check(whole_number(0, 4));
  occlusion->add_flag("--probe-row", occ->probe_row,
                      "Add a diagnostic row: Ideal with a box query before every block it draws");
  occlusion->add_flag("--flush-row", occ->flush_row,
                      "Add a diagnostic row: Ideal with a glFlush after every block");
  occlusion
      ->add_option("--poll-every", occ->poll_every,
                   "Add a CHC row that polls answers every N blocks (ChcOptions::poll_interval)")
      ->check(whole_number(0, 0xffffffffu));
  occlusion->add_option("--tau", occ->hlod_tau, "HLOD table: tau, pixels of error (default 1)")
      ->check(finite_number(0.0, 1e6));
  occlusion
      ->add_option("--psnr-frames", occ->psnr_frames,
                   "HLOD table: frames of the path the PSNR against Bool is taken on")
      ->check(whole_number(0, 100000));
  occlusion
      ->add_option("--csv", occ->csv_dir,
                   "Folder for the HLOD table's per-frame CSV (occlusion_SCENE.csv)")
      ->check(non_empty_path());
  occlusion->add_option("--latency", occ->latency,
                        "GPU-latency model: answers no earlier than N frames (Nf) or N "
                        "microseconds (Nus) after their issue (default 0: as the device answers)");
  occlusion->add_flag("--no-hlod", occ->no_hlod, "Print the CHC table only");
  occlusion->add_flag("--no-chc", occ->no_chc, "Print the HLOD table only");
  occlusion->callback([occ] { run_bench_occlusion(*occ); });
}

}  // namespace

void add_bench_commands(CLI::App& app) {
  auto* bench =
      app.add_subcommand("bench", "Benchmarks that print the tables of docs/benchmarks.md");
  bench->require_subcommand(1);
  add_bench_build_command(*bench);
  add_bench_occlusion_command(*bench);
  add_bench_scene_command(*bench);
  add_bench_cache_command(*bench);
}

}  // namespace treecut::cli
