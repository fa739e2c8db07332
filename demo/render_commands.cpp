// treecut render (headless, OSMesa) | treecut view (GLFW window): the run
// loop and the command lines; what render writes (stats.csv, summary.json,
// plot.svg, the output folder guard) is in render_reports.cpp.
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numeric>
#include <optional>

#include "commands.hpp"
#include "headless_gl.hpp"
#include "messages.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "render_reports.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/model.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/frame_rate.hpp"
#include "treecut/splat/image.hpp"
#include "view_script.hpp"
#include "viewer.hpp"

namespace treecut::cli {

namespace {

// The calling thread's CPU time (the render thread's: llvmpipe rasterizes on
// threads of its own, and --sync runs the stage's step() outside it).
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

struct RenderArgs {
  SceneArgs scene;
  std::string gl = "auto";  // headless back end (--gl)
  std::string path;
  std::string out = "render-out";
  int frames = 120;
  int width = 1280;
  int height = 720;
  double orbit_seconds = 8.0;
  int warmup = 30;
  bool sync = false;
  bool psnr = false;
  int stability = 0;
  bool no_png = false;
  double target_fps = 0.0;  // > 0: the viewer's governor adapts the strategy's knob
};

// Every input of render checked before any output (exit 2 with one line).
void check_render_inputs(const RenderArgs& a, const StrategyRegistry& registry) {
  check_params(registry, a.scene.strategies, a.scene.params);  // exit 2 before any work
  for (const std::string& name : a.scene.strategies) {
    if (a.target_fps > 0.0 &&
        !splat::FrameRateGovernor::for_strategy(*make_strategy(registry, name, {}), 1)) {
      throw InputError(name + ": --target-fps needs a max_nodes or min_size parameter");
    }
  }
  check_output_folder(a.out, a.scene.strategies, {a.scene.model, a.path});
}

// A model drawn from its pages (a .tch with --memory): what does not work
// on one yet is refused before any output.
void check_paged(const RenderArgs& a) {
  const std::string model = a.scene.model;
  if (a.psnr || a.stability > 0)
    throw InputError(model +
                     ": --psnr and --stability compare with the model at full detail, which a "
                     "model drawn from its pages (--memory) does not hold");
}

// A model drawn from its pages: its pages' line.
void describe_pages(const RenderArgs& a, const PagedHierarchy& paged) {
  const PagingStats s = paged.stats();
  const double gpu = double(splat::GpuNodePool::budget(paged, gpu_pool_options(a.scene)));
  char limited[96] = "";
  if (a.scene.memory != 0 && paged.memory_budget() < a.scene.memory)
    std::snprintf(limited, sizeof limited, ", what the GPU budget draws, not --memory's %.1f MiB",
                  double(a.scene.memory) / (1 << 20));
  std::printf(
      "pages     %llu in the file, drawn within %.1f MiB of memory (%llu bytes a node%s) and "
      "%.1f MiB of GPU memory (%llu), %.1f MiB copied up a frame at most; the finest detail at "
      "one place needs %.1f MiB of memory\n",
      static_cast<unsigned long long>(s.pages), double(paged.memory_budget()) / (1 << 20),
      static_cast<unsigned long long>(paged.bytes_per_node()), limited, gpu / (1 << 20),
      static_cast<unsigned long long>(splat::GpuNodePool::kVertexBytes),
      double(a.scene.gpu_upload) / (1 << 20), double(paged.full_detail_memory()) / (1 << 20));
}

// A scene's models drawn from their pages: their pages' line.
void describe_scene_pages(const RenderArgs& a, const Scene& scene,
                          const std::vector<PagedHierarchy*>& paged) {
  std::uint64_t pages = 0, memory = 0;
  for (const PagedHierarchy* p : paged) pages += p->stats().pages, memory += p->memory_budget();
  const double gpu =
      double(splat::GpuNodePool::budget(pool_models(scene), gpu_pool_options(a.scene)));
  std::printf(
      "pages     %zu of %zu models drawn from their pages (%llu pages in their files), within "
      "%.1f MiB of memory and %.1f MiB of GPU memory, %.1f MiB copied up a frame at most\n",
      paged.size(), scene.world->models.size(), static_cast<unsigned long long>(pages),
      double(memory) / (1 << 20), gpu / (1 << 20), double(a.scene.gpu_upload) / (1 << 20));
}

// The scene or model line; a scene past a strategy's per-object limit is
// refused first, before any output, naming the file.
void describe_scene(const RenderArgs& a, const StrategyRegistry& registry, const Scene& scene) {
  const std::vector<PagedHierarchy*> paged = paged_models(scene);
  if (!paged.empty()) check_paged(a);
  if (const std::shared_ptr<const StageScene>& world = scene.world) {
    for (const std::string& name : a.scene.strategies) {
      if (const std::string why =
              per_object_limit_problem(*world, *make_strategy(registry, name, {}));
          !why.empty()) {
        throw InputError(a.scene.model + ": " + why);
      }
    }
    std::printf("scene     %s: %zu objects of %zu models, %llu points at full detail\n",
                scene.label.c_str(), world->objects.size(), world->models.size(),
                static_cast<unsigned long long>(scene.instanced_points));
  } else {
    const Hierarchy& h = *scene.hierarchy;
    std::printf("model     %s: %u points, %u nodes\n", scene.label.c_str(), h.leaf_count(),
                h.node_count());
  }
  if (scene.paged) describe_pages(a, *scene.paged);
  if (scene.world && !paged.empty()) describe_scene_pages(a, scene, paged);
}

// The full-detail reference of --psnr and --stability: a model's leaves, or
// every object of a scene at its model's leaves (one leaf list per model,
// shared by its instances).
void upload_full_detail(const RenderArgs& a, const Scene& scene, splat::Renderer& renderer,
                        splat::CutBuffer& full, splat::SceneCutBuffer& full_scene) {
  const Hierarchy& h = *scene.hierarchy;
  const std::shared_ptr<const StageScene>& world = scene.world;
  if ((a.psnr || a.stability > 0) && world) {
    std::vector<const Hierarchy*> models;
    std::vector<std::vector<NodeId>> leaves;
    for (const auto& m : world->models) {
      models.push_back(m.get());
      const TreeCut all = TreeCut::leaf_cut(*m);
      leaves.emplace_back(all.nodes().begin(), all.nodes().end());
    }
    renderer.set_models(models);
    std::vector<std::span<const NodeId>> lists;
    for (const SceneObject& o : world->objects) lists.emplace_back(leaves[o.model]);
    full_scene.set_objects(renderer, world->objects);
    full_scene.upload(models, lists);
  } else if (a.psnr || a.stability > 0) {
    full.upload(h, TreeCut::leaf_cut(h).nodes());
  }
}

// What every strategy's run draws with: the scene along the path, the
// renderer and the full-detail reference.
struct RenderRig {
  const RenderArgs& a;
  const Scene& scene;
  const splat::CameraPath& path;
  const splat::RenderSettings& settings;
  glm::ivec2 size;
  splat::Renderer& renderer;
  const splat::CutBuffer& full;
  const splat::SceneCutBuffer& full_scene;
  std::string renderer_name;  // renderer_line(): what summary.json names

  [[nodiscard]] splat::Camera camera_at(double t) const {
    splat::Camera c = path.at(t);
    splat::fit_clip_planes(c, scene.center, scene.radius);
    return c;
  }
  void draw_full(const splat::Camera& c) const {
    if (scene.world) {
      renderer.draw_scene(full_scene, c, settings, true);
    } else {
      renderer.draw(full, c, settings, true);
    }
  }
  [[nodiscard]] splat::Image grab() const {
    return splat::Image{a.width, a.height, renderer.read_pixels()};
  }
};

StageOptions render_stage_options(const RenderArgs& a) {
  StageOptions stage_options;
  stage_options.launch = a.sync ? Launch::Manual : Launch::Thread;
  // llvmpipe keeps both cores busy while it draws: the stage takes what is left.
  stage_options.priority = StagePriority::Idle;
  configure_stage(stage_options, a.scene);
  return stage_options;
}

// What the last frame() call measured, beside its time.
struct LastFrame {
  splat::QueryStats before;  // the executor's totals before the frame
  splat::FrameResult result;
  double cpu_ms = 0.0;  // its render-thread CPU time
};

std::size_t cut_size(const splat::RenderThreadFrame& frame_loop, bool scene) {
  return scene ? frame_loop.scene_cut().size() : frame_loop.cut().size();
}

// The process's resident memory now (/proc/self/statm's second field, in
// pages); 0 where it cannot be read.
std::uint64_t resident_set_bytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return 0;
  unsigned long long size = 0, resident = 0;
  const int read = std::fscanf(f, "%llu %llu", &size, &resident);
  std::fclose(f);
  return read == 2 ? resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE)) : 0;
}

// A paged model's GPU pool and the process's memory in this frame's row
// (the budgets hold in every frame: tests read these columns).
void add_pool_counters(const splat::GpuNodePool& pool, Counters& c) {
  const splat::GpuPoolStats g = pool.stats();
  c.set("gpu_resident_mib", double(g.resident_bytes) / double(1 << 20), "MiB");
  c.set("gpu_pages", double(g.resident_pages), "pages");
  c.set("gpu_uploaded_kib", double(g.uploaded_bytes) / 1024.0, "KiB");
  c.set("gpu_stand_ins", double(g.stand_ins), "nodes");
  c.set("gpu_waiting_pages", double(g.waiting_pages), "pages");
  c.set("rss_mib", double(resident_set_bytes()) / double(1 << 20), "MiB");
}

// The row of frame f (time t, drawn in `ms`): the stage's counters and this
// frame's queries (the difference of the executor's totals).
FrameRow frame_row(int f, double t, double ms, const StageCounters& counters,
                   const splat::RenderThreadFrame& frame_loop, bool scene, const LastFrame& last,
                   const splat::QueryStats& q) {
  FrameRow row;
  row.frame = f;
  row.time_s = t;
  row.frame_ms = ms;
  row.cut_size = cut_size(frame_loop, scene);
  row.points = scene ? frame_loop.scene_cut().points() : frame_loop.cut().points();
  row.objects = last.result.objects;
  row.draw_calls = last.result.stats.draw_calls;
  row.render_cpu_ms = last.cpu_ms;
  row.iteration_ms = double(counters.iteration_ns_last) * 1e-6;
  row.exchanges = counters.exchanges;
  row.iterations = counters.iterations;
  row.converged = counters.converged;
  row.queries_issued = q.issued - last.before.issued;
  row.queries_answered = q.answered - last.before.answered;
  row.queries_pending = q.pending;
  if (row.queries_answered > 0) {
    row.query_latency_frames_mean =
        double(q.latency_frames_total - last.before.latency_frames_total) /
        double(row.queries_answered);
    row.query_latency_frames_max = q.latency_frames_max_last;
  }
  row.query_cpu_us = double(q.cpu_ns_total - last.before.cpu_ns_total) * 1e-3;
  // The named counters of the last completed iteration (with --sync, the
  // one after this frame), whatever the strategy publishes.
  row.counters = counters.last.counters;
  if (const splat::GpuNodePool* pool = frame_loop.gpu_pool())
    add_pool_counters(*pool, row.counters);
  return row;
}

// The frame just drawn as frame_NNNNN.png in `dir`, and its PSNR against
// full detail (which draws over it).
void record_image(const RenderRig& rig, const std::filesystem::path& dir, int f,
                  const splat::Camera& cam, FrameRow& row) {
  const RenderArgs& a = rig.a;
  if (a.no_png && !a.psnr) return;
  const splat::Image lod = rig.grab();
  if (!a.no_png) {
    char file[32];
    std::snprintf(file, sizeof file, "frame_%05d.png", f);
    splat::write_png(dir / file, lod);
  }
  if (a.psnr) {
    rig.draw_full(cam);
    const splat::Image reference = rig.grab();
    row.psnr_db = splat::psnr(lod, reference);
    row.psnr_luma_db = luma_psnr(lod, reference);
  }
}

// Static camera at the end of the path: let the strategy converge, then
// count the pixels that still change from one frame to the next. `frame`
// draws one frame.
template <class Frame>
void measure_stability(const RenderRig& rig, Frame& frame, const Controller& controller,
                       const splat::RenderThreadFrame& frame_loop, const splat::Camera& cam,
                       RunSummary& run) {
  for (int i = 0; i < 600 && !controller.stage().counters().converged; ++i) frame(cam);
  run.stability_converged = controller.stage().counters().converged;
  splat::Image previous = rig.grab();
  double sum = 0.0, worst = 0.0;
  for (int i = 0; i < rig.a.stability; ++i) {
    frame(cam);
    splat::Image current = rig.grab();
    const double changed = splat::changed_fraction(previous, current);
    sum += changed;
    worst = std::max(worst, changed);
    previous = std::move(current);
  }
  run.stability_frames = rig.a.stability;
  run.stability_changed = sum / rig.a.stability;
  run.stability_max = worst;
  run.converged_cut = cut_size(frame_loop, rig.scene.world != nullptr);
  rig.draw_full(cam);
  run.converged_psnr = splat::psnr(previous, rig.grab());
}

// The run's query totals and, for a scene, its size and the peak memory.
void add_run_totals(RunSummary& run, const splat::QueryStats& queries, std::uint64_t frames,
                    const StageScene* world) {
  run.queries = queries;
  run.query_frames = frames;
  if (world) {
    run.objects = world->objects.size();
    run.models = world->models.size();
    run.object_nodes = world->object_nodes();
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    run.peak_rss_mib = double(usage.ru_maxrss) / 1024.0;  // Linux: KiB
  }
}

// The summary line of a strategy's run, and the scene, queries, counters,
// shortfall and governor lines where they apply.
void print_run(const RenderArgs& a, const std::string& name, const RunSummary& run, bool scene,
               const splat::QueryStats& q, const Controller& controller,
               const StageOptions& stage_options,
               const std::optional<splat::FrameRateGovernor>& governor) {
  std::printf(
      "%-13s %d frames: frame %.2f ms (median %.2f), cut %.0f nodes, iteration %.2f ms, "
      "%llu exchanges",
      name.c_str(), a.frames, mean_of(run.rows, &FrameRow::frame_ms), median_frame_ms(run.rows),
      std::accumulate(run.rows.begin(), run.rows.end(), 0.0,
                      [](double s, const FrameRow& r) { return s + double(r.cut_size); }) /
          double(run.rows.size()),
      mean_of(run.rows, &FrameRow::iteration_ms),
      static_cast<unsigned long long>(run.rows.back().exchanges));
  if (a.psnr) {
    const double mean = mean_psnr(run.rows);
    if (std::isfinite(mean))
      std::printf(", PSNR %.2f dB", mean);
    else
      std::printf(", PSNR %s dB (identical to full detail)", psnr_text(mean).c_str());
    std::printf(", luma PSNR %.2f dB", mean_of(run.rows, &FrameRow::psnr_luma_db));
  }
  if (a.stability > 0) {
    std::printf(", stability %.5f changed (max %.5f)%s", run.stability_changed, run.stability_max,
                run.stability_converged ? "" : " [not converged]");
  }
  std::printf("\n");
  if (scene) {
    std::printf(
        "scene     %s: %zu objects, %.1f draw calls per frame, render thread %.3f ms CPU per "
        "frame, stage iteration %.2f ms, peak RSS %.0f MiB\n",
        name.c_str(), run.objects,
        std::accumulate(run.rows.begin(), run.rows.end(), 0.0,
                        [](double s, const FrameRow& r) { return s + double(r.draw_calls); }) /
            double(run.rows.size()),
        mean_of(run.rows, &FrameRow::render_cpu_ms), mean_of(run.rows, &FrameRow::iteration_ms),
        run.peak_rss_mib);
  }
  // Only a strategy that posts GPU queries gets this line.
  if (q.issued > 0 || q.answered > 0) {
    std::printf(
        "queries   %s: %llu issued, %llu answered (%llu occluded), %zu pending, "
        "%llu dropped, latency %.2f frames (max %llu), %.3f ms per frame\n",
        name.c_str(), static_cast<unsigned long long>(q.issued),
        static_cast<unsigned long long>(q.answered), static_cast<unsigned long long>(q.occluded),
        q.pending, static_cast<unsigned long long>(q.dropped), q.latency_frames_mean(),
        static_cast<unsigned long long>(q.latency_frames_max),
        double(q.cpu_ns_total) * 1e-6 / double(std::max<std::uint64_t>(controller.frame(), 1)));
  }
  if (const std::string line = counters_line(run.rows); !line.empty()) {
    std::printf("counters  %s: %s\n", name.c_str(), line.c_str());
  }
  // Fewer iterations than the path needed: say so (the frames lag or show the root).
  if (const std::string late =
          stage_shortfall(name, controller.stage().counters(), stage_options,
                          static_cast<int>(controller.stage().counters().frames));
      !late.empty()) {
    std::fflush(stdout);
    print_warning(late);
  }
  if (governor) {
    std::printf("governor  %s = %.6g at the end, model %.2f ms + %.4g us/splat\n",
                governor->param().c_str(), governor->value(), governor->fixed_ms(),
                governor->per_splat_ms() * 1e3);
  }
}

// One strategy along the path (its frames into `dir`), then its
// stability, its files and its lines.
RunSummary run_strategy(const RenderRig& rig, const StrategyRegistry& registry,
                        const std::string& name, const std::filesystem::path& dir) {
  const RenderArgs& a = rig.a;
  const std::shared_ptr<const StageScene>& world = rig.scene.world;
  const Hierarchy& h = *rig.scene.hierarchy;
  splat::Camera cam = rig.camera_at(0.0);
  const StageOptions stage_options = render_stage_options(a);
  // A scene's per-object instances come from this factory (make_strategy
  // with the same parameters); a model's one instance too.
  const StrategyFactory factory = [&registry, &name, &a] {
    return make_strategy(registry, name, a.scene.params);
  };
  std::unique_ptr<Strategy> strategy = world ? nullptr : factory();
  // The viewer's governor (--target-fps), fed the same way: frame time and
  // the splats that frame drew.
  std::optional<splat::FrameRateGovernor> governor;
  if (a.target_fps > 0.0) {
    governor = splat::FrameRateGovernor::for_strategy(
        *factory(), world ? static_cast<std::size_t>(world->object_nodes()) : h.node_count());
  }
  // The scene's hierarchy itself (no copy): the renderer's vertex buffer is
  // of the hierarchy in the stage's lists, so it is never uploaded again.
  std::optional<Controller> controller_storage;
  const ViewSnapshot first_view = splat::view_snapshot(cam, rig.size, rig.settings.light);
  if (world) {
    controller_storage.emplace(world, factory, first_view, stage_options);
  } else {
    controller_storage.emplace(Model{rig.scene.hierarchy, TreeCut::root_cut(h), rig.scene.paged},
                               std::move(strategy), first_view, stage_options);
  }
  Controller& controller = *controller_storage;
  splat::QueryExecutor queries;
  splat::RenderThreadFrame frame_loop(controller, rig.renderer, &queries);
  frame_loop.follow_pages(rig.scene.paged.get(), gpu_pool_options(a.scene));
  LastFrame last;
  auto frame = [&](const splat::Camera& c) {
    last.before = queries.stats();
    const double cpu0 = thread_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    last.result = frame_loop.run_render_thread(c, rig.settings, true);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    last.cpu_ms = thread_cpu_ms() - cpu0;
    if (governor) {
      if (auto v = governor->update(ms, last.result.stats.splats, a.target_fps)) {
        controller.set_param(governor->param(), *v);
      }
    }
    // Synchronous mode: the stage's iteration runs here, outside the frame
    // time, and the pages it asked for are read before the next frame (a
    // run that replays the same, whatever the machine's load).
    if (a.sync) {
      controller.stage().step();
      for (PagedHierarchy* p : paged_models(rig.scene)) (void)p->wait_idle(60000);
    }
    return ms;
  };

  RunSummary run;
  run.strategy = name;
  run.renderer = rig.renderer_name;
  // On a terminal, once the run has taken a second: the frame it is at.
  const std::string label = "render " + name;
  ProgressBar bar(label);
  for (int i = 0; i < a.warmup; ++i) frame(cam);
  for (int f = 0; f < a.frames; ++f) {
    bar.update(label, static_cast<std::size_t>(f), static_cast<std::size_t>(a.frames));
    const double t = rig.path.frame_time(f, a.frames);
    cam = rig.camera_at(t);
    const double ms = frame(cam);
    FrameRow row = frame_row(f, t, ms, controller.stage().counters(), frame_loop, world != nullptr,
                             last, queries.stats());
    record_image(rig, dir, f, cam, row);
    run.rows.push_back(row);
  }
  if (a.stability > 0) measure_stability(rig, frame, controller, frame_loop, cam, run);
  bar.finish();

  add_run_totals(run, queries.stats(), controller.frame(), world.get());
  write_stats_csv(dir / "stats.csv", run.rows);
  write_file_atomically(dir / "summary.json", summary_json(run));
  print_run(a, name, run, world != nullptr, queries.stats(), controller, stage_options, governor);
  if (const splat::GpuNodePool* pool = frame_loop.gpu_pool()) {
    // The pool's map from node ids to vertices (4 B a node up, in reserved
    // address space): the memory pages the system holds under it.
    std::printf(
        "memory    GPU pool: %.1f MiB of memory pages under the slots of %.1f MiB of "
        "vertices up\n",
        double(pool->held_slot_bytes()) / (1 << 20),
        double(pool->stats().resident_bytes) / (1 << 20));
  }
  // Pages that could not be read: a line each (their parents stayed leaves).
  for (PagedHierarchy* p : paged_models(rig.scene))
    for (const std::string& problem : p->take_problems()) print_warning(problem);
  return run;
}

void run_render(const RenderArgs& a) {
  if (a.frames < 1) throw InputError("--frames must be at least 1");
  splat::RenderSettings settings = render_settings(a.scene);  // validates --mode early
  (void)color_by(a.scene);                                    // and the colour options
  const StrategyRegistry registry = make_registry(a.scene);
  check_render_inputs(a, registry);
  const float aspect = float(a.width) / float(a.height);
  splat::CameraPath path;
  if (!a.path.empty()) path = splat::load_camera_path(a.path);

  ProgressBar opening("open");
  const Scene scene = load_scene(a.scene, opening.callback());
  opening.finish();
  apply_model_settings(settings, a.scene, scene);
  std::string color_note;
  const splat::ColorBy colors = resolve_color(scene, a.scene, &color_note);
  check_coloring(scene, colors);  // exit 2 before any output
  // A scene file: its objects go through the stage (per object, or a
  // scene-level strategy) and are drawn by draw_scene in one call per pass.
  if (a.path.empty())
    path = splat::orbit_path(scene.view_min, scene.view_max, aspect, a.orbit_seconds, 73, scene.up);
  describe_scene(a, registry, scene);

  const std::unique_ptr<splat::GlContext> context = open_headless(a.gl, a.width, a.height);
  std::printf("renderer  %s, %dx%d, %s splats%s\n", renderer_line(*context).c_str(), a.width,
              a.height, std::string(splat::splat_mode_name(settings.mode)).c_str(),
              settings.eye_dome > 0.0f ? ", eye-dome lighting" : "");
  splat::Renderer renderer(*scene.hierarchy, {a.width, a.height}, pool_vertices(scene, a.scene));
  if (!color_note.empty()) std::printf("colour    %s\n", color_note.c_str());
  if (const splat::Legend legend = apply_coloring(scene, colors, renderer); legend.title != "rgb") {
    std::printf("colour    %s\n", legend_line(legend).c_str());
  }
  splat::CutBuffer full;
  splat::SceneCutBuffer full_scene;
  upload_full_detail(a, scene, renderer, full, full_scene);
  const RenderRig rig{a,
                      scene,
                      path,
                      settings,
                      glm::ivec2(a.width, a.height),
                      renderer,
                      full,
                      full_scene,
                      renderer_line(*context)};

  const std::filesystem::path out(a.out);
  make_output_folder(out);
  mark_output_folder(out);
  std::vector<RunSummary> runs;
  for (const std::string& name : a.scene.strategies) {
    const std::filesystem::path dir = a.scene.strategies.size() > 1 ? out / name : out;
    make_output_folder(dir);
    runs.push_back(run_strategy(rig, registry, name, dir));
  }
  if (const std::vector<PagedHierarchy*> paged = paged_models(scene); !paged.empty()) {
    // What the budget counts (the resident nodes' bytes) against what the
    // system holds under the arrays (with the memory pages their runs' ends
    // share): the part of RSS that is the models'.
    std::uint64_t held = 0, resident = 0, budget = 0;
    for (const PagedHierarchy* p : paged)
      held += p->held_bytes(), resident += p->stats().resident_bytes, budget += p->memory_budget();
    std::printf(
        "memory    node arrays: %.1f MiB of memory pages for %.1f MiB of resident nodes "
        "(budget %.1f MiB)\n",
        double(held) / (1 << 20), double(resident) / (1 << 20), double(budget) / (1 << 20));
  }
  write_plot_svg(out / "plot.svg", runs, scene.label + ": per frame, per strategy");
  std::printf("wrote     %s (stats.csv, summary.json, plot.svg%s)\n", quoted_name(out).c_str(),
              a.no_png ? "" : ", frame_*.png");
}

}  // namespace

void add_render_commands(CLI::App& app) {
  auto ra = std::make_shared<RenderArgs>();
  auto* render = app.add_subcommand(
      "render", "Render frames headless (OSMesa) along a camera path; write PNGs and statistics");
  add_scene_options(*render, ra->scene);
  // No CLI::ExistingFile on --path/--script: load_camera_path and
  // load_view_script say what a bad path is ("is a FIFO", "is a directory").
  render->add_option("--path", ra->path, "Camera path file (default: one orbit around the model)")
      ->check(non_empty_path());
  render->add_option("-n,--frames", ra->frames, "Frames along the path")
      ->check(whole_number(1, 1000000))
      ->capture_default_str();
  render->add_option("-o,--out", ra->out, "Output folder")
      ->check(non_empty_path())
      ->capture_default_str();
  add_gl_option(render, &ra->gl);
  render->add_option("--width", ra->width, "Frame width")
      ->check(whole_number(16, 8192))
      ->capture_default_str();
  render->add_option("--height", ra->height, "Frame height")
      ->check(whole_number(16, 8192))
      ->capture_default_str();
  render->add_option("--orbit-seconds", ra->orbit_seconds, "Duration of the default orbit")
      ->check(finite_number(0.1, 3600.0))
      ->capture_default_str();
  render->add_option("--warmup", ra->warmup, "Frames rendered at the first camera before recording")
      ->check(whole_number(0, 100000))
      ->capture_default_str();
  render->add_flag(
      "--sync", ra->sync,
      "Run the Feedback Stage synchronously, one iteration per frame (deterministic: a "
      "paged model's pages it asks for are read before the next frame)");
  render->add_flag("--psnr", ra->psnr, "Also render full detail per frame and record the PSNR");
  render
      ->add_option("--stability", ra->stability,
                   "After the path: converge at the last camera, then measure this many frames "
                   "of temporal stability")
      ->check(whole_number(0, 100000));
  render->add_flag("--no-png", ra->no_png, "Write statistics only");
  render
      ->add_option("--target-fps", ra->target_fps,
                   "Adapt the strategy's budget to hold this frame rate, as the viewer (0 = off)")
      ->check(finite_number(0.0, 1000.0));
  render->callback([ra] { run_render(*ra); });

  auto va = std::make_shared<ViewArgs>();
  auto* view = app.add_subcommand("view", "Open a window on a model (GLFW, OpenGL 4.5 core)");
  // The window's default look is hq (issue 30: fast mode's discs, lit once
  // each, look scaly up close); render keeps fast, what its tables measure.
  va->scene.mode = "hq";
  add_scene_options(*view, va->scene);
  view->add_option("MORE", va->more_models, "Further models; O in the window opens the next")
      ->check(non_empty_path());
  view->add_option("--width", va->width, "Window width")
      ->check(whole_number(16, 8192))
      ->capture_default_str();
  view->add_option("--height", va->height, "Window height")
      ->check(whole_number(16, 8192))
      ->capture_default_str();
  view->add_option("--path", va->path, "Replay this camera path")->check(non_empty_path());
  view->add_option("--script", va->script,
                   "Scripted run (see docs/camera-paths.md): replay, screenshot, exit")
      ->check(non_empty_path());
  view->add_option("--screenshot-dir", va->screenshot_dir, "Where F12 / scripts save PNGs")
      ->check(non_empty_path())
      ->capture_default_str();
  view->add_option("--target-fps", va->target_fps,
                   "Adapt the strategy's budget to hold this frame rate (0 = off): full detail "
                   "where the machine draws it that fast")
      ->check(finite_number(0.0, 1000.0))
      ->capture_default_str();
  view->callback([va] {
    // The inputs are checked before a window opens (and where there is no
    // display), as render checks them: a bad path or script is exit 2 with
    // FILE:LINE, an unknown strategy or parameter, or one that cannot run on
    // the scene given, exit 2 naming it.
    if (!va->path.empty()) (void)splat::load_camera_path(va->path);
    const StrategyRegistry registry = make_registry(va->scene);
    const std::string strategy =
        va->scene.strategies.empty() ? std::string("optimization") : va->scene.strategies.front();
    check_params(registry, {strategy}, va->scene.params);
    const bool scene = !va->scene.model.empty() && looks_like_scene(va->scene.model);
    if (const std::string why = scene_strategy_problem(*registry.create(strategy));
        scene && !why.empty())
      throw InputError(quoted_name(va->scene.model) + ": " + why);
    if (!va->script.empty()) {
      ScriptChecks checks{&registry, strategy, scene ? va->scene.model : std::string()};
      (void)load_view_script(va->script, checks);
    }
    const int code = run_viewer(*va);
    if (code != 0) throw std::runtime_error("viewer failed");
  });
}

}  // namespace treecut::cli
