// treecut bench scene SCENE --path WALK: the `budget` strategy (Peng & Cao,
// I3D 2013, ../shared/papers/occlusion-culling-with-parallel-lod.txt) along a
// walkthrough, with HZM culling on and off at the same budget N, against the
// exact reference of the renderer: every object in the frustum drawn at full
// detail (its model's leaves) in SplatMode::ObjectId and read back, as
// tests/culling/hzm_gl_test.cpp does. Per frame:
//   - accuracy: objects the HZM culled / objects truly hidden (in the
//     strategy's frustum and no pixel of their id), and the wrongly culled
//     (culled with a pixel: must be 0);
//   - the points (splats selected) given to the objects the reference sees;
//   - the luma PSNR (render --psnr's luma_psnr) of each budgeted image
//     against the full-detail image;
//   - the draw time of each budgeted cut (draw_scene + glFinish: wall and
//     process CPU, llvmpipe's threads included) and the splats drawn.
// A diagnosis table reruns the strategy's culler (HzmCuller on the
// strategy's own objects, read-only) with other parameters on the same
// reference: what the missed hidden objects would need (a finer test level,
// an exact depth image, more occluders).
//
// The strategies are iterated directly (as the stage's step() would, with
// no previous lists: the budget strategy is a function of the view), so
// both see the same cameras and nothing of the stage's timing.
#include "bench_scene.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "headless_gl.hpp"
#include "option_checks.hpp"
#include "render_reports.hpp"
#include "treecut/culling/hzm.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/file_io.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/splat/scene_draw.hpp"
#include "treecut/strategies/budget_strategy.hpp"
#include "treecut/tree_cut.hpp"
#include "viewer.hpp"

namespace treecut::cli {

namespace {

namespace many = strategies::many;

constexpr const char* kCsvHeader =
    "frame,in_frustum,seen,hidden,culled,wrongly,accuracy,selected_on,selected_off,"
    "to_seen_on,to_seen_off,splats_on,splats_off,draw_ms_on,draw_ms_off,draw_cpu_ms_on,"
    "draw_cpu_ms_off,iteration_ms_on,iteration_ms_off,psnr_luma_on,psnr_luma_off";

struct SceneBenchArgs {
  std::string scene;
  std::string gl = "auto";  // headless back end (--gl)
  std::string path;
  int frames = 12;
  // The part of the walk measured, in path seconds (to < 0: its end): the
  // street part of a walk without the overviews, whose full detail is every
  // object of the scene.
  double from = 0.0;
  double to = -1.0;
  int width = 1280;
  int height = 720;
  std::vector<std::string> params;  // "name=value" for the budget strategy
  std::string csv_dir;
  bool no_psnr = false;
  bool no_diagnosis = false;
};

// Process CPU time (every thread: llvmpipe rasterizes on its own threads).
double process_cpu_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) * 1e3 +
         double(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-3;
}

double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (const double x : v) s += x;
  return v.empty() ? std::numeric_limits<double>::quiet_NaN() : s / double(v.size());
}

// One budget strategy (culling on or off) and what its iterations gave.
struct Side {
  // The built-in strategy itself (this benchmark measures its phases and
  // reads its visible set), made here rather than through the registry.
  std::unique_ptr<strategies::BudgetStrategy> strategy;
  std::vector<NodeId> nodes;
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint8_t> visible;
  splat::SceneCutBuffer buffer;
  // Per frame.
  std::vector<double> selected, to_seen, splats, draw_ms, draw_cpu_ms, iteration_ms, psnr;
  std::vector<double> occlusion_culled, visible_count;
};

// A rerun of the strategy's culler with other parameters (diagnosis).
struct Variant {
  std::string name;
  culling::HzmParams params;
  std::unique_ptr<culling::HzmCuller> culler;
  std::size_t culled = 0;   // hidden and culled, over the frames
  std::size_t wrongly = 0;  // culled with a pixel
  std::size_t rescued = 0;  // of the strategy's missed hidden objects, culled here
};

std::filesystem::path csv_path(const std::filesystem::path& dir, const std::string& scene) {
  return dir / ("scene_" + std::filesystem::path(scene).stem().string() + ".csv");
}

std::string csv_number(double v) {
  if (!std::isfinite(v)) return "";
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

// The inputs of a run, every one checked before any work (exit 2 with one line).
struct SceneBenchInputs {
  splat::CameraPath path;
  double to = 0.0;  // the end of the part of the walk measured
  SceneArgs scene_args;
  std::filesystem::path csv;  // empty: no CSV
};

SceneBenchInputs check_scene_bench_args(const SceneBenchArgs& a) {
  SceneBenchInputs in{splat::load_camera_path(a.path), 0.0, {}, {}};
  in.to = walk_part_end(in.path, a.path, a.from, a.to);
  require_regular_file(a.scene);
  if (!looks_like_scene(a.scene)) {
    throw InputError(a.scene + ": not a scene file (bench scene takes a .scene)");
  }
  in.scene_args.model = a.scene;
  in.scene_args.strategies = {"budget"};
  in.scene_args.params = a.params;
  const StrategyRegistry registry = make_registry(in.scene_args);
  check_params(registry, in.scene_args.strategies, a.params);
  for (const std::string& p : a.params) {
    if (parse_param(p).first == "culling") {
      throw InputError("-p " + p + ": bench scene runs culling on and off itself");
    }
  }
  in.csv = a.csv_dir.empty() ? std::filesystem::path() : csv_path(a.csv_dir, a.scene);
  if (!in.csv.empty()) check_bench_csv(in.csv, kCsvHeader, "bench scene");
  return in;
}

// The two budget strategies, culling on and off, with the same parameters.
void make_sides(Side& on, Side& off, const std::vector<std::string>& params,
                const StageScene& world) {
  for (Side* s : {&on, &off}) {
    s->strategy = std::make_unique<strategies::BudgetStrategy>();
    apply_params(*s->strategy, params);
    s->strategy->set_param("culling", s == &on ? 1.0 : 0.0);
    s->strategy->reset_scene(world);
  }
}

// Every model at full detail (its leaves, one list per model shared by its
// instances), and the points of every object at full detail.
struct FullDetail {
  std::vector<const Hierarchy*> models;
  std::vector<std::vector<NodeId>> leaves;
  std::uint64_t points = 0;
};

FullDetail full_detail(const StageScene& world) {
  FullDetail full;
  for (const auto& m : world.models) {
    full.models.push_back(m.get());
    const TreeCut all = TreeCut::leaf_cut(*m);
    full.leaves.emplace_back(all.nodes().begin(), all.nodes().end());
  }
  for (const SceneObject& o : world.objects) full.points += full.leaves[o.model].size();
  return full;
}

// The diagnosis: the strategy's culler rerun on its objects with other
// parameters. The first one repeats the strategy's own settings (a check
// that the rerun reproduces it).
std::vector<Variant> diagnosis_variants(const SceneBenchArgs& a, std::size_t aos, float ct) {
  std::vector<Variant> variants;
  const auto add = [&](std::string name, std::size_t active, float threshold, int finer,
                       unsigned depth_width, culling::Facing facing = culling::HzmParams{}.facing) {
    Variant v;
    v.name = std::move(name);
    v.params.active = active;
    v.params.compactness_threshold = threshold;
    v.params.finer_levels = finer;
    v.params.depth_width = depth_width;
    v.params.facing = facing;
    variants.push_back(std::move(v));
  };
  const unsigned cells = culling::HzmParams{}.depth_width;
  const int finer = culling::HzmParams{}.finer_levels;
  const auto label = [&](std::size_t active, float threshold, int f, unsigned w) {
    char b[128];
    std::snprintf(b, sizeof b, "AOS %zu, CT %.2f, finer %d, %u cells", active, double(threshold), f,
                  w);
    return std::string(b);
  };
  add(label(aos, ct, finer, cells) + " (the strategy's)", aos, ct, finer, cells);
  add(label(aos, ct, 0, cells) + " (Eq. 5 only)", aos, ct, 0, cells);
  add(label(aos, ct, 10, cells) + " (every cell)", aos, ct, 10, cells);
  const unsigned exact = static_cast<unsigned>(std::max(a.width, a.height));
  add(label(aos, ct, 10, exact) + " (exact depth)", aos, ct, 10, exact);
  add(label(2 * aos, ct, finer, cells), 2 * aos, ct, finer, cells);
  add(label(4 * aos, ct, finer, cells), 4 * aos, ct, finer, cells);
  add(label(16 * aos, ct, 10, exact), 16 * aos, ct, 10, exact);
  // The other reading of E in Eq. 3 than the strategy's (hzm.hpp, Facing).
  const bool to_object = culling::HzmParams{}.facing == culling::Facing::EyeToObject;
  const culling::Facing other =
      to_object ? culling::Facing::ViewDirection : culling::Facing::EyeToObject;
  const std::string other_name =
      to_object ? ", Eq. 3 E = viewing direction" : ", Eq. 3 E = eye to object";
  add(label(aos, ct, finer, cells) + other_name, aos, ct, finer, cells, other);
  add(label(4 * aos, ct, 10, exact) + other_name, 4 * aos, ct, 10, exact, other);
  add(label(aos, 0.3f, finer, cells), aos, 0.3f, finer, cells);
  add(label(aos, 0.9f, finer, cells), aos, 0.9f, finer, cells);
  for (Variant& v : variants) v.culler = std::make_unique<culling::HzmCuller>(v.params);
  return variants;
}

// What every frame draws with (made once) and its scratch.
struct FrameRig {
  const SceneBenchArgs& a;
  const StageScene& world;
  splat::Renderer& renderer;
  const FullDetail& full;
  splat::SceneCutBuffer& reference;
  const splat::RenderSettings& color;  // fast splats, as render's default
  const splat::RenderSettings& ids;    // ObjectId
  std::vector<Variant>& variants;
  WorkerPool& pool;
  std::vector<std::uint32_t> seen;  // per object: its pixels in the reference
  std::vector<std::span<const NodeId>> lists;
  const std::vector<NodeId> none;
};

// One iteration of a side's strategy at `view`, timed, and what it selected.
void iterate_side(Side& s, const StageScene& world, const ViewSnapshot& view) {
  s.nodes.clear();
  s.offsets.clear();
  std::vector<QueryRequest> queries;
  const SceneIterationInput in{world, view, nullptr, s.strategy->params_version(), {}, {}};
  SceneIterationOutput out;
  out.nodes = &s.nodes;
  out.offsets = &s.offsets;
  out.queries = &queries;
  const auto t0 = std::chrono::steady_clock::now();
  s.strategy->iterate_scene(in, out);
  s.iteration_ms.push_back(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  s.visible.assign(s.strategy->visible().begin(), s.strategy->visible().end());
  s.selected.push_back(double(s.nodes.size()));
  s.occlusion_culled.push_back(double(s.strategy->last().occlusion_culled));
  s.visible_count.push_back(double(s.strategy->last().visible));
}

void upload_side(FrameRig& rig, Side& s) {
  for (std::size_t i = 0; i < rig.lists.size(); ++i) {
    rig.lists[i] =
        std::span<const NodeId>(s.nodes.data() + s.offsets[i], s.offsets[i + 1] - s.offsets[i]);
  }
  s.buffer.upload(rig.full.models, rig.lists);
}

// A side's cut drawn (draw_scene + glFinish); `record`: its times and splats kept.
void draw_side(FrameRig& rig, Side& s, const splat::Camera& cam, bool record) {
  const double cpu0 = process_cpu_ms();
  const auto t0 = std::chrono::steady_clock::now();
  const splat::FrameStats st = rig.renderer.draw_scene(s.buffer, cam, rig.color, true);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!record) return;
  s.draw_cpu_ms.push_back(process_cpu_ms() - cpu0);
  s.draw_ms.push_back(ms);
  s.splats.push_back(double(st.splats));
}

splat::Image grab(const FrameRig& rig) {
  return splat::Image{rig.a.width, rig.a.height, rig.renderer.read_pixels()};
}

// The reference: every object in the strategy's frustum (culling off:
// visible = in the frustum) at full detail, its id per pixel, counted into
// rig.seen; with PSNR also its color image, returned.
splat::Image draw_reference(FrameRig& rig, const Side& off, const splat::Camera& cam) {
  const std::size_t n = rig.lists.size();
  for (std::size_t i = 0; i < n; ++i) {
    rig.lists[i] = off.visible[i]
                       ? std::span<const NodeId>(rig.full.leaves[rig.world.objects[i].model])
                       : std::span<const NodeId>(rig.none);
  }
  rig.reference.upload(rig.full.models, rig.lists);
  rig.renderer.draw_scene(rig.reference, cam, rig.ids, true);
  std::fill(rig.seen.begin(), rig.seen.end(), 0u);
  {
    const std::vector<std::uint8_t> px = rig.renderer.read_pixels();
    for (std::size_t p = 0; p + 3 < px.size(); p += 4) {
      const std::uint32_t v = px[p] | (px[p + 1] << 8) | (px[p + 2] << 16);
      if (v < n) ++rig.seen[v];
    }
  }
  splat::Image full;
  if (!rig.a.no_psnr) {
    rig.renderer.draw_scene(rig.reference, cam, rig.color, true);
    full = grab(rig);
  }
  return full;
}

// One frame's objects in the frustum against the reference.
struct FrameCounts {
  std::size_t in_frustum = 0, seen_objects = 0, hidden = 0, culled = 0, wrongly = 0;
};

// Counts the objects of the frustum by what the reference and the HZM
// (culling on) made of them, and the points each side gave to the seen
// ones; `missed`: the hidden objects the HZM kept.
FrameCounts classify_objects(const std::vector<std::uint32_t>& seen, Side& on, Side& off,
                             std::vector<std::uint8_t>& missed) {
  FrameCounts c;
  double to_seen_on = 0.0, to_seen_off = 0.0;
  for (std::size_t i = 0; i < seen.size(); ++i) {
    if (!off.visible[i]) continue;
    ++c.in_frustum;
    const bool hzm_culled = !on.visible[i];
    if (seen[i] > 0) {
      ++c.seen_objects;
      c.wrongly += hzm_culled ? 1 : 0;
      to_seen_on += double(on.offsets[i + 1] - on.offsets[i]);
      to_seen_off += double(off.offsets[i + 1] - off.offsets[i]);
    } else {
      ++c.hidden;
      c.culled += hzm_culled ? 1 : 0;
      missed[i] = hzm_culled ? 0 : 1;
    }
  }
  on.to_seen.push_back(to_seen_on);
  off.to_seen.push_back(to_seen_off);
  return c;
}

// The diagnosis on the same reference: each variant's culler on the
// strategy's objects. Returns the hidden occluders the first variant (the
// strategy's own settings) kept.
std::size_t diagnose(FrameRig& rig, const Side& on, const Side& off, const ViewSnapshot& view,
                     const std::vector<std::uint8_t>& missed) {
  const std::vector<std::uint32_t>& seen = rig.seen;
  std::size_t hidden_aos = 0;
  const std::span<const culling::ObjectBounds> objects = on.strategy->objects();
  for (Variant& v : rig.variants) {
    v.culler->preprocess(objects);
    v.culler->cull(objects, view, &rig.pool);
    const auto vis = v.culler->visible();
    const auto states = v.culler->states();
    for (std::size_t i = 0; i < seen.size(); ++i) {
      if (!off.visible[i] || states[i] != culling::ObjectState::Occluded) continue;
      if (seen[i] > 0) {
        ++v.wrongly;
      } else {
        ++v.culled;
        v.rescued += missed[i];
      }
    }
    (void)vis;
    if (&v == &rig.variants.front()) {
      for (const std::uint32_t k : v.culler->active())
        hidden_aos += seen[k] == 0 && states[k] != culling::ObjectState::Occluded ? 1 : 0;
    }
  }
  return hidden_aos;
}

// The accuracy figures per frame, and their sums over the frames.
struct AccuracySeries {
  std::vector<double> in_frustum, seen, hidden, culled, wrongly, accuracy;
  std::vector<double> missed_occluder;  // hidden occluders the HZM kept
  std::size_t hidden_all = 0, culled_all = 0, wrongly_all = 0;

  void add(const FrameCounts& c, std::size_t hidden_aos) {
    in_frustum.push_back(double(c.in_frustum));
    seen.push_back(double(c.seen_objects));
    hidden.push_back(double(c.hidden));
    culled.push_back(double(c.culled));
    wrongly.push_back(double(c.wrongly));
    accuracy.push_back(c.hidden > 0 ? double(c.culled) / double(c.hidden)
                                    : std::numeric_limits<double>::quiet_NaN());
    missed_occluder.push_back(double(hidden_aos));
    hidden_all += c.hidden;
    culled_all += c.culled;
    wrongly_all += c.wrongly;
  }
};

// Frame f of `frames`: both sides iterated at the camera, the reference
// drawn, the objects classified, the diagnosis rerun, both cuts drawn.
void run_frame(FrameRig& rig, Side& on, Side& off, const splat::Camera& cam, int f, int frames,
               AccuracySeries& series) {
  const glm::ivec2 size(rig.a.width, rig.a.height);
  const ViewSnapshot view = splat::view_snapshot(cam, size, rig.color.light);
  iterate_side(on, rig.world, view);
  iterate_side(off, rig.world, view);
  const splat::Image full = draw_reference(rig, off, cam);

  std::vector<std::uint8_t> missed(rig.seen.size(), 0);
  const FrameCounts counts = classify_objects(rig.seen, on, off, missed);
  const std::size_t hidden_aos = diagnose(rig, on, off, view, missed);

  for (Side* s : {&on, &off}) {
    upload_side(rig, *s);
    if (f == 0) draw_side(rig, *s, cam, false);  // untimed: the GPU's caches warm
    draw_side(rig, *s, cam, true);
    if (!rig.a.no_psnr) s->psnr.push_back(luma_psnr(grab(rig), full));
  }
  series.add(counts, hidden_aos);
  std::fprintf(stderr, "frame %d/%d: %zu in the frustum, %zu hidden, %zu culled\n", f + 1, frames,
               counts.in_frustum, counts.hidden, counts.culled);
}

void print_accuracy_table(int frames, const AccuracySeries& s) {
  const double accuracy = s.hidden_all > 0 ? double(s.culled_all) / double(s.hidden_all)
                                           : std::numeric_limits<double>::quiet_NaN();
  double acc_min = std::numeric_limits<double>::infinity(), acc_max = -acc_min;
  for (const double x : s.accuracy) {
    if (!std::isfinite(x)) continue;
    acc_min = std::min(acc_min, x);
    acc_max = std::max(acc_max, x);
  }
  std::printf(
      "\nCulling accuracy against the exact reference (means per frame; accuracy = culled / "
      "hidden over all frames)\n");
  std::printf(
      "| frames | in frustum | seen (reference) | truly hidden | HZM culled | wrongly culled | "
      "hidden occluders kept | accuracy | per frame min / max |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  std::printf("| %d | %.1f | %.1f | %.1f | %.1f | %zu | %.1f | %.4f (%zu / %zu) | %.4f / %.4f |\n",
              frames, mean(s.in_frustum), mean(s.seen), mean(s.hidden), mean(s.culled),
              s.wrongly_all, mean(s.missed_occluder), accuracy, s.culled_all, s.hidden_all,
              std::isfinite(acc_min) ? acc_min : 0.0, std::isfinite(acc_max) ? acc_max : 0.0);
}

void print_on_off_table(std::uint64_t points, const Side& on, const Side& off) {
  const auto psnr_text_of = [](const std::vector<double>& v) {
    if (v.empty()) return std::string("-");
    double lo = std::numeric_limits<double>::infinity();
    for (const double x : v) lo = std::min(lo, x);
    char b[64];
    std::snprintf(b, sizeof b, "%.2f (min %.2f)", mean(v), lo);
    return std::string(b);
  };
  std::printf("\nCulling on and off at the same budget N = %llu (means per frame unless said)\n",
              static_cast<unsigned long long>(points));
  std::printf("| | culling on | culling off | on / off |\n");
  std::printf("|---|---:|---:|---:|\n");
  const auto row = [](const char* name, double x, double y, const char* fmt) {
    char bx[48], by[48];
    std::snprintf(bx, sizeof bx, fmt, x);
    std::snprintf(by, sizeof by, fmt, y);
    std::printf("| %s | %s | %s | %.4f |\n", name, bx, by, y != 0.0 ? x / y : 0.0);
  };
  row("potentially visible objects", mean(on.visible_count), mean(off.visible_count), "%.1f");
  row("splats selected", mean(on.selected), mean(off.selected), "%.0f");
  row("splats to objects the reference sees", mean(on.to_seen), mean(off.to_seen), "%.0f");
  row("share of the splats to seen objects", mean(on.to_seen) / std::max(mean(on.selected), 1.0),
      mean(off.to_seen) / std::max(mean(off.selected), 1.0), "%.4f");
  row("splats drawn", mean(on.splats), mean(off.splats), "%.0f");
  row("draw ms (median, wall, glFinish)", median(on.draw_ms), median(off.draw_ms), "%.2f");
  row("draw CPU ms (median, process)", median(on.draw_cpu_ms), median(off.draw_cpu_ms), "%.2f");
  row("strategy iteration ms (median)", median(on.iteration_ms), median(off.iteration_ms), "%.2f");
  std::printf("| luma PSNR against full detail, dB | %s | %s | |\n", psnr_text_of(on.psnr).c_str(),
              psnr_text_of(off.psnr).c_str());
}

void print_diagnosis_table(const std::vector<Variant>& variants, const AccuracySeries& s) {
  if (variants.empty()) return;
  std::printf(
      "\nDiagnosis: the strategy's culler rerun with other parameters on the same frames and "
      "reference (rescued = of the %zu hidden objects the strategy kept, culled here)\n",
      s.hidden_all - s.culled_all);
  std::printf("| culler | accuracy | culled | wrongly | rescued |\n");
  std::printf("|---|---:|---:|---:|---:|\n");
  for (const Variant& v : variants) {
    std::printf("| %s | %.4f | %zu | %zu | %zu |\n", v.name.c_str(),
                s.hidden_all > 0 ? double(v.culled) / double(s.hidden_all) : 0.0, v.culled,
                v.wrongly, v.rescued);
  }
}

void write_scene_csv(const std::filesystem::path& csv, int frames, const AccuracySeries& s,
                     const Side& on, const Side& off) {
  std::ostringstream o;
  o << kCsvHeader << "\n";
  for (std::size_t f = 0; f < std::size_t(frames); ++f) {
    const auto at = [f](const std::vector<double>& v) {
      return f < v.size() ? v[f] : std::numeric_limits<double>::quiet_NaN();
    };
    o << f << ',' << csv_number(at(s.in_frustum)) << ',' << csv_number(at(s.seen)) << ','
      << csv_number(at(s.hidden)) << ',' << csv_number(at(s.culled)) << ','
      << csv_number(at(s.wrongly)) << ',' << csv_number(at(s.accuracy)) << ','
      << csv_number(at(on.selected)) << ',' << csv_number(at(off.selected)) << ','
      << csv_number(at(on.to_seen)) << ',' << csv_number(at(off.to_seen)) << ','
      << csv_number(at(on.splats)) << ',' << csv_number(at(off.splats)) << ','
      << csv_number(at(on.draw_ms)) << ',' << csv_number(at(off.draw_ms)) << ','
      << csv_number(at(on.draw_cpu_ms)) << ',' << csv_number(at(off.draw_cpu_ms)) << ','
      << csv_number(at(on.iteration_ms)) << ',' << csv_number(at(off.iteration_ms)) << ','
      << csv_number(at(on.psnr)) << ',' << csv_number(at(off.psnr)) << "\n";
  }
  write_bench_csv(csv, o.str());
}

void run_bench_scene(const SceneBenchArgs& a) {
  const SceneBenchInputs in = check_scene_bench_args(a);
  const splat::CameraPath& path = in.path;

  const Scene scene = load_scene(in.scene_args);
  const StageScene& world = *scene.world;
  const std::size_t n = world.objects.size();
  if (n >= splat::kMaxSceneDrawObjects) {
    throw InputError(a.scene + ": more objects than the ObjectId reference can tell apart");
  }
  Side on, off;
  make_sides(on, off, a.params, world);
  const auto points = static_cast<std::uint64_t>(on.strategy->param("points"));
  const auto aos = static_cast<std::size_t>(on.strategy->param("occluders"));
  const auto ct = static_cast<float>(on.strategy->param("ct"));

  const glm::ivec2 size(a.width, a.height);
  const std::unique_ptr<splat::GlContext> context = open_headless(a.gl, a.width, a.height);
  splat::Renderer renderer(*scene.hierarchy, size);
  const FullDetail full = full_detail(world);
  renderer.set_models(full.models);
  const std::vector<SceneObject>& draws = world.objects;
  splat::SceneCutBuffer reference;
  reference.set_objects(renderer, draws);
  on.buffer.set_objects(renderer, draws);
  off.buffer.set_objects(renderer, draws);
  splat::RenderSettings color;  // fast splats, as render's default
  splat::RenderSettings ids;
  ids.mode = splat::SplatMode::ObjectId;

  const int frames = std::max(a.frames, 1);
  std::printf("scene     %s: %zu objects of %zu models, %llu points at full detail\n",
              scene.label.c_str(), n, world.models.size(),
              static_cast<unsigned long long>(full.points));
  std::printf(
      "renderer  %s, %dx%d, fast splats; reference: ObjectId image of the objects in "
      "the frustum at full detail\n",
      renderer_line(*context).c_str(), a.width, a.height);
  std::printf(
      "path      %s: %d frames from %.1f to %.1f s of %.1f; budget N = %llu, AOS %zu, CT %.2f\n",
      a.path.c_str(), frames, a.from, in.to, path.duration(),
      static_cast<unsigned long long>(points), aos, double(ct));
  std::fflush(stdout);

  std::vector<Variant> variants;
  if (!a.no_diagnosis) variants = diagnosis_variants(a, aos, ct);
  WorkerPool pool(2);
  FrameRig rig{a,
               world,
               renderer,
               full,
               reference,
               color,
               ids,
               variants,
               pool,
               std::vector<std::uint32_t>(n),
               std::vector<std::span<const NodeId>>(n),
               {}};
  AccuracySeries series;
  for (int f = 0; f < frames; ++f) {
    const double t = a.from + (frames == 1 ? 0.0 : (in.to - a.from) * f / (frames - 1));
    splat::Camera cam = path.at(t);
    splat::fit_clip_planes(cam, scene.center, scene.radius);
    run_frame(rig, on, off, cam, f, frames, series);
  }

  print_accuracy_table(frames, series);
  print_on_off_table(points, on, off);
  print_diagnosis_table(variants, series);
  std::fflush(stdout);
  if (!in.csv.empty()) write_scene_csv(in.csv, frames, series, on, off);
}

}  // namespace

void add_bench_scene_command(CLI::App& bench) {
  auto args = std::make_shared<SceneBenchArgs>();
  auto* cmd = bench.add_subcommand(
      "scene",
      "The budget strategy on a scene's walk, culling on and off at the same N, against the "
      "renderer's exact ObjectId reference: culling accuracy, points to visible objects, luma "
      "PSNR against full detail, draw time (docs/many-objects.md)");
  cmd->add_option("SCENE", args->scene, "Scene file (e.g. made by treecut gen city-block)")
      ->check(non_empty_path())
      ->required();
  cmd->add_option("--path", args->path, "Camera path (gen city-block --walk FILE)")
      ->check(non_empty_path())
      ->required();
  cmd->add_option("--frames", args->frames, "Frames evenly spaced over the path")
      ->check(whole_number(1, 100000))
      ->capture_default_str();
  cmd->add_option("--from", args->from, "Start of the part of the path measured, seconds")
      ->check(finite_number(0.0, 1e6));
  cmd->add_option("--to", args->to, "Its end, seconds (default: the end of the path)")
      ->check(finite_number(0.0, 1e6));
  cmd->add_option("-p,--param", args->params,
                  "Budget strategy parameter name=value (points, alpha, pet, occluders, ct, "
                  "threads; culling is run both ways)");
  add_gl_option(cmd, &args->gl);
  cmd->add_option("--width", args->width, "Width in pixels")
      ->check(whole_number(16, 8192))
      ->capture_default_str();
  cmd->add_option("--height", args->height, "Height in pixels")
      ->check(whole_number(16, 8192))
      ->capture_default_str();
  cmd->add_option("--csv", args->csv_dir, "Folder for the per-frame CSV (scene_SCENE.csv)")
      ->check(non_empty_path());
  cmd->add_flag("--no-psnr", args->no_psnr, "Skip the full-detail color image and the PSNR");
  cmd->add_flag("--no-diagnosis", args->no_diagnosis,
                "Skip the reruns of the culler with other parameters");
  cmd->callback([args] { run_bench_scene(*args); });
}

}  // namespace treecut::cli
