// Model, strategy and frame set-up shared by `treecut render` and `treecut view`.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <limits>

#include "messages.hpp"
#include "option_checks.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/frame_rate.hpp"
#include "treecut/strategies/builtin.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tools/scene_generate.hpp"
#include "view_script.hpp"
#include "viewer.hpp"

namespace treecut::cli {

namespace {

// The budgets of a model drawn from its pages, and a URL's stall timeout.
void add_paging_options(CLI::App& cmd, SceneArgs& args) {
  add_memory_option(cmd, args.memory, true);
  add_gpu_memory_options(cmd, args.gpu_memory, args.gpu_upload);
  cmd.add_option("--stall-timeout", args.stall_timeout_s,
                 "A cache by URL (http:// or https://, read by range requests): seconds a read "
                 "may receive nothing before it fails (its page is named, the rest drawn)")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
}

}  // namespace

void add_scene_options(CLI::App& cmd, SceneArgs& args) {
  cmd.add_option("MODEL", args.model,
                 "A point file (PLY, LAS, PCD, XYZ, PTS, CSV), a .tch cache or a .scene file "
                 "(default: a generated model, see --default-kind)")
      ->check(non_empty_path());
  cmd.add_option("--default-kind", args.default_kind,
                 "Procedural model used without MODEL: sphere | terrain | city | plant")
      ->capture_default_str();
  cmd.add_option("--default-points", args.default_points, "Points of the generated model")
      ->check(whole_number(1, std::uint64_t{1} << 28))
      ->capture_default_str();
  cmd.add_option("-s,--strategy", args.strategies,
                 "LOD strategy (optimization, bucket, recursive or a plugin's); render accepts "
                 "several and runs the path once per strategy")
      ->capture_default_str();
  cmd.add_option("-p,--param", args.params, "Strategy parameter NAME=VALUE (repeatable)");
  cmd.add_option("--plugin", args.plugins, "Load strategies from a plugin shared library")
      ->check(non_empty_path());
  cmd.add_option("-m,--mode", args.mode, "Splat mode: fast | hq | fixed")->capture_default_str();
  cmd.add_option("--radius-scale", args.radius_scale, "Multiply every splat radius")
      ->check(finite_number(0.05, 20.0))
      ->capture_default_str();
  cmd.add_option("--point-size", args.point_size, "Point size in pixels of the fixed mode")
      ->check(finite_number(1.0, 64.0))
      ->capture_default_str();
  cmd.add_option("-k,--neighbours", args.k, "Neighbours for normals and radii of point clouds")
      ->check(whole_number(3, 64))
      ->capture_default_str();
  cmd.add_option("--up", args.up,
                 "Up axis of the model: x | y | z | -x | -y | -z | auto (a depth camera's "
                 "viewpoint, else from the data: a ground or base, the way the normals face, a "
                 "flat extent; see docs/rendering.md)")
      ->check(CLI::IsMember({"auto", "x", "y", "z", "-x", "-y", "-z", "+x", "+y", "+z"}))
      ->capture_default_str();
  cmd.add_option("--points",
                 "The budget in points (splats drawn at most): the strategy's "
                 "max_nodes, or a scene budget's points")
      ->check(finite_number(1.0, 4e9))
      ->each([&args](const std::string& v) { args.params.push_back("budget=" + v); });
  // Checked as it is parsed: a reversed box is refused before the model is
  // read (and before a stale cache is rebuilt for nothing).
  cmd.add_option_function<std::vector<double>>(
         "--clip",
         [&args](const std::vector<double>& box) {
           check_box_corners(box, "--clip: ");
           args.clip = box;
         },
         "Draw only what lies in the box X0 Y0 Z0 X1 Y1 Z1 (the file's coordinates)")
      ->expected(6)
      ->check(finite_number(-1e18, 1e18));
  cmd.add_option("--edl", args.edl,
                 "Eye-dome lighting (depth edges darkened, as in Potree): auto turns it on for "
                 "models without normals of their own")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  cmd.add_option("--edl-strength", args.edl_strength,
                 "Eye-dome lighting's strength (1: Potree's factor, too strong for discs)")
      ->check(finite_number(0.01, 100.0))
      ->capture_default_str();
  cmd.add_flag("--unlit", args.unlit,
               "The colours as the file has them, unshaded (coloured scans carry their own light)");
  cmd.add_flag("--fixed-light", args.fixed_light,
               "Keep the light fixed in the world instead of following the camera");
  cmd.add_flag("--validate", args.validate,
               "Check every cut a strategy returns with TreeCut::validate (always on in Debug "
               "and sanitizer builds; see docs/plugin-guide.md)");
  cmd.add_option("--blend", args.blend_frames,
                 "Frames over which the splats of an exchanged cut fade in and the replaced ones "
                 "out (screen-door dither; 0 = swap at once; docs/rendering.md, \"Fades\")")
      ->check(whole_number(0, 64))
      ->capture_default_str();
  cmd.add_option("--color", args.color,
                 "Colour by: rgb (the file's colours), elevation, or an attribute of the model "
                 "(intensity, classification, ...; `treecut info` lists them); auto: rgb where "
                 "the file has usable colours, else intensity where it varies, else elevation")
      ->capture_default_str();
  cmd.add_option("--color-map", args.color_map,
                 "Colour map: auto (classes for categories, viridis for the rest) | viridis | "
                 "grey | classes (the ASPRS palette for classification)")
      ->check(CLI::IsMember({"auto", "viridis", "grey", "gray", "classes"}))
      ->capture_default_str();
  cmd.add_option("--color-range", args.color_range,
                 "The values at the ends of the map, LOW HIGH (default: the 2nd and 98th "
                 "percentiles of the points; a cache drawn from its pages: their extremes)")
      ->expected(2);
  cmd.add_option("--classes", args.classes,
                 "Show only these classes (2,6: ground and buildings) or hide some (-7,-18: "
                 "noise) of the classification attribute");
  add_columns_option(cmd, args.columns);
  add_crs_option(cmd, args.crs);
  add_paging_options(cmd, args);
  cmd.add_option("--stage-wait-bound", args.stage_wait_bound_ms,
                 "Milliseconds an update may wait for the low-priority Feedback Stage before it "
                 "runs at normal priority until done (0 = never; docs/threading.md)")
      ->check(whole_number(0, 3600000))
      ->capture_default_str();
}

void configure_stage(StageOptions& options, const SceneArgs& args) {
  options.blend_frames = args.blend_frames;
  if (args.validate) options.validate = true;
  options.starvation_bound = std::chrono::milliseconds(args.stage_wait_bound_ms);
  // The stage cannot leave while the iteration runs (it reads the stage's
  // lists and the model); the program is done with both, so it ends here.
  options.on_slow_cancel = [](const std::string& what) {
    std::fflush(stdout);
    print_error(what + "; exiting");
    std::_Exit(1);
  };
}

std::string stage_shortfall(const std::string& strategy, const StageCounters& c,
                            const StageOptions& options, int frames) {
  char line[320];
  if (c.iterations == 0) {
    std::snprintf(line, sizeof line,
                  "%s: no strategy iteration completed in %d frames; they show the initial cut",
                  strategy.c_str(), frames);
    return line;
  }
  // With the raise off (bound 0) a wait is still late past the default bound.
  const std::chrono::milliseconds bound = options.starvation_bound.count() > 0
                                              ? options.starvation_bound
                                              : StageOptions{}.starvation_bound;
  const auto bound_ns = static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(bound).count());
  if (c.wait_ns_max > bound_ns) {
    std::snprintf(line, sizeof line,
                  "%s: the Feedback Stage fell behind: an update waited up to %.0f ms to start "
                  "(bound %lld ms; %llu iterations in %d frames, priority raised %llu times)",
                  strategy.c_str(), double(c.wait_ns_max) * 1e-6,
                  static_cast<long long>(bound.count()),
                  static_cast<unsigned long long>(c.iterations), frames,
                  static_cast<unsigned long long>(c.boosts));
    return line;
  }
  return {};
}

Scene load_scene(const SceneArgs& args) {
  return load_scene(args, {});
}

namespace {

// The median splat radius of at most ~64k leaves spread over H.
float typical_splat(const Hierarchy& h, std::span<const NodeRange> known) {
  std::vector<float> radii;
  for (const NodeId n : sample_leaves(h, known, 65536)) radii.push_back(h.splat_radius(n));
  if (radii.empty()) return 0.0f;
  const auto mid = radii.begin() + static_cast<std::ptrdiff_t>(radii.size() / 2);
  std::nth_element(radii.begin(), mid, radii.end());
  return *mid;
}

// Scene::view_min/max from the bounds and a splat of radius SPLAT.
void set_view_box(Scene& s, float splat) {
  const glm::vec3 center = 0.5f * (s.bounds_min + s.bounds_max);
  const glm::vec3 half =
      glm::max(0.5f * (s.bounds_max - s.bounds_min) + splat, glm::vec3(4.0f * splat));
  s.view_min = center - half;
  s.view_max = center + half;
}

}  // namespace

splat::GpuPoolOptions gpu_pool_options(const SceneArgs& args) {
  splat::GpuPoolOptions o;
  o.memory_bytes = args.gpu_memory;
  o.upload_bytes = args.gpu_upload;
  return o;
}

std::vector<PagedHierarchy*> paged_models(const Scene& scene) {
  std::vector<PagedHierarchy*> out;
  if (scene.paged) out.push_back(scene.paged.get());
  if (scene.world)
    for (const auto& p : scene.world->paged)
      if (p) out.push_back(p.get());
  return out;
}

std::vector<splat::PoolModel> pool_models(const Scene& scene) {
  std::vector<splat::PoolModel> out;
  if (!scene.world || scene.world->paged.empty()) return out;
  for (std::size_t m = 0; m < scene.world->models.size(); ++m)
    out.push_back({scene.world->models[m].get(), scene.world->paged_model(m)});
  return out;
}

std::uint32_t pool_vertices(const Scene& scene, const SceneArgs& args) {
  try {
    if (scene.paged)
      return splat::GpuNodePool::segment_vertices(*scene.paged, gpu_pool_options(args));
    if (const std::vector<splat::PoolModel> models = pool_models(scene); !models.empty())
      return splat::GpuNodePool::segment_vertices(models, gpu_pool_options(args));
    return 0;
  } catch (const InputError& e) {
    throw InputError(args.model + ": " + e.what());
  }
}

namespace {

// A scene file (looks_like_scene): its objects for the stage, the camera
// fit to their points.
Scene load_scene_file(const SceneArgs& args) {
  Scene s;
  SceneLoadOptions so;
  so.parse.generator = tools::scene_generator();
  so.open.attributes.k = args.k;
  so.open.crs = args.crs;
  so.open.memory = args.memory;
  so.open.warn = [](const std::string& w) { print_warning(w); };
  if (args.memory != 0) {
    // Its caches drawn from their pages within --memory (issue 45), no
    // more of them in memory than the GPU budget draws.
    so.paging.emplace();
    so.paging->memory_bytes = args.memory;
    so.paging->stall_ms = static_cast<int>(args.stall_timeout_s * 1000.0);
    if (args.gpu_memory != 0)
      so.paging->node_limit = splat::GpuNodePool::nodes_within(args.gpu_memory);
  }
  const treecut::Scene scene = treecut::load_scene(std::filesystem::path(args.model), so);
  s.world = stage_scene(scene);
  s.hierarchy = scene.models.front().hierarchy;
  s.instanced_points = scene.instanced_points();
  s.label = std::filesystem::path(args.model).filename().string();
  // The generated scenes are z up (docs/scene-files.md); --up may say otherwise.
  const std::optional<UpAxis> chosen = parse_up_axis(args.up);
  s.up_axis = chosen ? *chosen : UpAxis{2, false, "a scene (z up)"};
  s.up = s.up_axis.vector();
  // The camera fits the objects' points as it fits a model's (its points'
  // bounds, not Scene::bounds, which adds the splats' reach): the world box
  // of each model's point bounds, so one object with the identity frames
  // exactly as its model does.
  s.bounds_min = glm::vec3(std::numeric_limits<float>::max());
  s.bounds_max = glm::vec3(std::numeric_limits<float>::lowest());
  for (const SceneObject& o : scene.objects) {
    const Hierarchy& m = *scene.models[o.model].hierarchy;
    for (int c = 0; c < 8; ++c) {
      const glm::vec3 corner((c & 1) ? m.bounds_max().x : m.bounds_min().x,
                             (c & 2) ? m.bounds_max().y : m.bounds_min().y,
                             (c & 4) ? m.bounds_max().z : m.bounds_min().z);
      const glm::vec3 w(o.world * glm::vec4(corner, 1.0f));
      s.bounds_min = glm::min(s.bounds_min, w);
      s.bounds_max = glm::max(s.bounds_max, w);
    }
  }
  s.center = 0.5f * (s.bounds_min + s.bounds_max);
  s.radius = std::max(0.5f * glm::length(s.bounds_max - s.bounds_min), 1e-6f);
  set_view_box(s, 0.0f);
  if (s.world->paged.empty()) {
    if (args.gpu_memory != 0)
      throw InputError(args.model +
                       ": --gpu-memory: the scene has no cache (.tch) to draw from its pages "
                       "(with --memory); a model held whole is on the GPU whole");
  } else {
    (void)pool_vertices(s, args);  // a GPU budget too small: refused now, in one line
  }
  return s;
}

// The up axis, bounds, first view box and sensor view of a model.
void frame_model(Scene& s, const SceneArgs& args) {
  const Hierarchy& h = *s.hierarchy;
  // What the model has read: a paged model its root's page (the rest comes
  // as the view asks; reading it now would read nothing, and map the zero
  // page where the pages are written later: a copy and an interrupt of
  // every core for each 4 KiB when they are).
  std::vector<NodeRange> known{{0, h.node_count()}};
  if (s.paged) s.paged->page_ranges(0, known);
  // The same rule for files and generated models: the data decides.
  const std::optional<UpAxis> chosen = parse_up_axis(args.up);
  s.up_axis = chosen ? *chosen : detect_up_axis(h, known);
  s.up = s.up_axis.vector();
  s.bounds_min = h.bounds_min();
  s.bounds_max = h.bounds_max();
  s.center = 0.5f * (h.bounds_min() + h.bounds_max());
  s.radius = std::max(0.5f * glm::length(h.bounds_max() - h.bounds_min()), 1e-6f);
  // A paged model's leaves are not read yet (the finest nodes of its root
  // page are coarse, and its leaves there outliers with wide discs, which
  // moved the first view of a survey far back): the bounds alone. A model
  // of more than a page is far larger than its splats.
  set_view_box(s, s.paged && s.paged->pages() > 1 ? 0.0f : typical_splat(h, known));
  if (const std::optional<Viewpoint>& v = h.frame().viewpoint) {
    // The camera looks along its +z with +y down (PCL's convention).
    splat::Camera c;
    c.eye = glm::vec3(v->position - h.frame().origin);
    const glm::vec3 forward(v->orientation * glm::dvec3(0.0, 0.0, 1.0));
    c.target = c.eye + forward * std::max(glm::distance(c.eye, s.center), 1e-3f);
    c.up = glm::vec3(v->orientation * glm::dvec3(0.0, -1.0, 0.0));
    splat::fit_clip_planes(c, s.center, s.radius + glm::distance(c.eye, s.center));
    s.sensor_view = c;
  }
}

}  // namespace

Scene load_scene(const SceneArgs& args, const LoadProgressFn& progress) {
  if (args.gpu_memory != 0 && !is_cache_url(args.model) &&
      !(args.memory != 0 && (looks_like_cache(args.model) || looks_like_scene(args.model))))
    throw InputError(
        "--gpu-memory: only a cache drawn from its pages (a .tch with --memory) is "
        "drawn within a GPU budget; a model held whole is on the GPU whole");
  if (!args.model.empty() && looks_like_scene(args.model)) return load_scene_file(args);
  Scene s;
  if (args.model.empty()) {
    const tools::ModelKind kind = tools::parse_model_kind(args.default_kind);
    s.hierarchy = std::make_shared<const Hierarchy>(
        build_from_points(tools::generate_model(kind, args.default_points, 1)));
    s.label =
        "generated " + args.default_kind + " (" + std::to_string(args.default_points) + " points)";
  } else if (is_cache_url(args.model) || (args.memory != 0 && looks_like_cache(args.model))) {
    // A cache with a memory budget, or by URL: drawn from its pages (issue
    // 45), within --memory (a URL without it: a build's default budget).
    PagingOptions paging;
    paging.memory_bytes = args.memory != 0 ? args.memory : default_build_budget();
    paging.stall_ms = static_cast<int>(args.stall_timeout_s * 1000.0);
    // No more in memory than the GPU budget draws.
    if (args.gpu_memory != 0) paging.node_limit = splat::GpuNodePool::nodes_within(args.gpu_memory);
    s.paged = PagedHierarchy::open(args.model, paging);
    s.hierarchy = std::shared_ptr<const Hierarchy>(s.paged, &s.paged->hierarchy());
    s.label = std::filesystem::path(args.model).filename().string() + " (paged)";
    (void)pool_vertices(s, args);  // a GPU budget too small: refused now, in one line
  } else {
    OpenOptions o;
    o.attributes.k = args.k;
    o.columns = args.columns;
    o.crs = args.crs;
    o.memory = args.memory;
    o.warn = [](const std::string& w) { print_warning(w); };
    o.progress = progress;
    s.hierarchy = std::make_shared<const Hierarchy>(open_model(args.model, o).hierarchy);
    const std::filesystem::path model(args.model);
    // A folder of tiles ("flight/") by its own name.
    s.label = (model.filename().empty() ? model.parent_path() : model).filename().string();
  }
  frame_model(s, args);
  return s;
}

splat::ColorBy color_by(const SceneArgs& args) {
  splat::ColorBy by;
  by.source = args.color;
  by.map = splat::parse_color_map(args.color_map);
  if (!args.color_range.empty()) {
    if (args.color_range.size() != 2 || !std::isfinite(args.color_range[0]) ||
        !std::isfinite(args.color_range[1]) || !(args.color_range[0] < args.color_range[1])) {
      throw InputError("--color-range: expected two finite numbers LOW HIGH with LOW < HIGH");
    }
    by.low = args.color_range[0];
    by.high = args.color_range[1];
  }
  if (!args.classes.empty()) splat::parse_class_filter(args.classes, by);
  return by;
}

namespace {

std::vector<const Hierarchy*> scene_models(const Scene& scene) {
  std::vector<const Hierarchy*> models;
  if (scene.world) {
    for (const auto& m : scene.world->models) models.push_back(m.get());
  } else {
    models.push_back(scene.hierarchy.get());
  }
  return models;
}

}  // namespace

namespace {

// A model drawn from its pages, as far as it is known when it opens: the
// leaves of its root page (each holds the points below it; nothing else is
// read yet, and reading it would map the zero page where pages go later).
std::vector<NodeId> known_leaves(const Hierarchy& h, const PagedHierarchy& paged) {
  std::vector<NodeRange> known;
  paged.page_ranges(0, known);
  return sample_leaves(h, known, 65536);
}

// Model I's pages (a scene's model I, or the model: I = 0), or null when it
// is held whole.
const PagedHierarchy* model_pages(const Scene& scene, std::size_t i) {
  return scene.world ? scene.world->paged_model(i) : scene.paged.get();
}

}  // namespace

splat::ColorBy resolve_color(const Scene& scene, const SceneArgs& args, std::string* note) {
  const PagedHierarchy* paged = model_pages(scene, 0);
  return splat::resolve_auto_color(
      *scene.hierarchy, color_by(args), note,
      paged ? known_leaves(*scene.hierarchy, *paged) : std::vector<NodeId>{});
}

void check_coloring(const Scene& scene, const splat::ColorBy& by) {
  for (const Hierarchy* h : scene_models(scene)) splat::check_color_by(*h, by);
}

splat::Legend apply_coloring(const Scene& scene, const splat::ColorBy& by,
                             splat::Renderer& renderer) {
  const std::vector<const Hierarchy*> models = scene_models(scene);
  const bool own = by.source == "rgb" && by.show_classes.empty() && by.hide_classes.empty();
  if (!paged_models(scene).empty()) {
    // Coloured as their pages go up to the GPU (node_pool.hpp): a paged
    // model from what the root page's leaves and the points' extremes say
    // (NodeColoring, partial), a scene's model held whole from all of it.
    splat::Legend legend;
    for (std::size_t i = 0; i < models.size(); ++i) {
      const PagedHierarchy* paged = model_pages(scene, i);
      std::shared_ptr<const splat::NodeColoring> rule;
      if (!own) {
        rule = std::make_shared<const splat::NodeColoring>(
            *models[i], by, scene.up,
            paged ? known_leaves(*models[i], *paged) : std::vector<NodeId>{}, paged != nullptr);
      }
      renderer.set_node_coloring(*models[i], rule);
      if (i == 0 && rule) legend = rule->legend();
    }
    if (own) legend.title = "rgb";
    return legend;
  }
  splat::Legend first;
  for (std::size_t i = 0; i < models.size(); ++i) {
    if (own) {
      renderer.set_node_colors(*models[i], {});
      continue;
    }
    splat::Coloring c = splat::color_nodes(*models[i], by, scene.up);
    if (i == 0) first = std::move(c.legend);
    renderer.set_node_colors(*models[i], std::move(c.colors));
  }
  if (own) first.title = "rgb";
  return first;
}

std::string legend_line(const splat::Legend& legend) {
  char text[160];
  if (legend.title == "rgb") return "rgb (the file's colours)";
  if (legend.continuous) {
    std::snprintf(text, sizeof text, "%s: %s from %.6g to %.6g", legend.title.c_str(),
                  std::string(splat::color_map_name(legend.map)).c_str(), legend.low, legend.high);
    return text;
  }
  std::string line = legend.title + ":";
  for (const splat::Legend::Entry& e : legend.entries) {
    if (std::isnan(e.share)) {
      std::snprintf(text, sizeof text, " %s%s,", e.label.c_str(), e.hidden ? " (hidden)" : "");
    } else {
      std::snprintf(text, sizeof text, " %s %.1f %%%s,", e.label.c_str(), 100.0 * e.share,
                    e.hidden ? " (hidden)" : "");
    }
    line += text;
  }
  if (line.back() == ',') line.pop_back();
  return line;
}

StrategyRegistry make_registry(const SceneArgs& args) {
  StrategyRegistry registry;
  strategies::register_builtin(registry);
  for (const std::string& p : args.plugins) registry.load_plugin(p);
  return registry;
}

std::pair<std::string, double> parse_param(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw InputError("--param '" + text + "': expected NAME=VALUE");
  }
  const std::string value = text.substr(eq + 1);
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (value.empty() || end != value.c_str() + value.size() || !std::isfinite(v)) {
    throw InputError("--param '" + text + "': '" + value + "' is not a finite number");
  }
  return {text.substr(0, eq), v};
}

// `--points N` is the parameter "budget": a strategy's budget in points,
// whatever it calls it (optimization's max_nodes, the scene budget's points).
std::string resolve_param(const std::string& key, const std::vector<ParamSpec>& specs) {
  if (key != "budget") return key;
  for (const char* name : {"max_nodes", "points"}) {
    if (std::any_of(specs.begin(), specs.end(), [&](const ParamSpec& s) { return s.name == name; }))
      return name;
  }
  return key;
}

std::unique_ptr<Strategy> make_strategy(const StrategyRegistry& registry, const std::string& name,
                                        const std::vector<std::string>& params) {
  std::unique_ptr<Strategy> s = registry.create(name);
  apply_params(*s, params);
  return s;
}

void apply_params(Strategy& strategy, const std::vector<std::string>& params) {
  for (const std::string& p : params) {
    // Named, not a structured binding: clang 14 cannot capture one in a lambda.
    const auto param = parse_param(p);
    const auto& specs = strategy.param_specs();
    const std::string key = resolve_param(param.first, specs);
    // With several strategies (render -s a -s b) a parameter applies to those that have it.
    if (std::none_of(specs.begin(), specs.end(),
                     [&](const ParamSpec& ps) { return ps.name == key; })) {
      continue;
    }
    strategy.set_param(key, param.second);
  }
}

void check_params(const StrategyRegistry& registry, const std::vector<std::string>& strategies,
                  const std::vector<std::string>& params) {
  for (const std::string& p : params) {
    const std::string key = parse_param(p).first;
    bool known = false;
    for (const std::string& name : strategies) {
      const auto specs = registry.create(name)->param_specs();
      const std::string resolved = resolve_param(key, specs);
      known |= std::any_of(specs.begin(), specs.end(),
                           [&](const ParamSpec& ps) { return ps.name == resolved; });
    }
    if (!known && key == "budget")
      throw InputError("--points: no selected strategy has a budget in points (max_nodes, points)");
    if (!known)
      throw InputError("--param " + p + ": no selected strategy has a parameter '" + key + "'");
  }
  for (const std::string& name : strategies) (void)make_strategy(registry, name, params);
}

TreeCut opening_cut(const Hierarchy& h) {
  return breadth_first_cut(h, static_cast<std::size_t>(splat::FrameRateGovernor::kFloorSplats));
}

splat::RenderSettings render_settings(const SceneArgs& args) {
  splat::RenderSettings r;
  r.mode = splat::parse_splat_mode(args.mode);
  r.radius_scale = args.radius_scale;
  r.point_size_px = args.point_size;
  r.light.unlit = args.unlit;
  if (args.fixed_light) {
    r.light.follow_camera = false;
    r.light.direction = {-0.4f, 0.8f, 0.45f};
  }
  r.eye_dome = args.edl == "on" ? args.edl_strength : 0.0f;
  return r;
}

void apply_model_settings(splat::RenderSettings& settings, const SceneArgs& args,
                          const Scene& scene) {
  bool estimated = scene.hierarchy && scene.hierarchy->frame().normals_estimated;
  if (scene.world) {
    for (const auto& m : scene.world->models) estimated = estimated || m->frame().normals_estimated;
  }
  settings.eye_dome =
      args.edl == "on" || (args.edl == "auto" && estimated) ? args.edl_strength : 0.0f;
  apply_clip(settings, args.clip, scene);
}

void apply_clip(splat::RenderSettings& settings, const std::vector<double>& box,
                const Scene& scene) {
  settings.clip = box.size() == 6;
  if (!settings.clip) return;
  // A map model's origin taken off in double; a scene's world as it is.
  const glm::dvec3 o =
      scene.world || !scene.hierarchy ? glm::dvec3(0.0) : scene.hierarchy->frame().origin;
  const glm::dvec3 a(box[0], box[1], box[2]);
  const glm::dvec3 b(box[3], box[4], box[5]);
  settings.clip_min = glm::vec3(a - o);
  settings.clip_max = glm::vec3(b - o);
  const glm::vec3 lo = scene.bounds_min, hi = scene.bounds_max;
  const bool apart = glm::any(glm::lessThan(settings.clip_max, lo)) ||
                     glm::any(glm::greaterThan(settings.clip_min, hi));
  if (apart) {
    print_warning("--clip: the box holds no point of the model (it lies within " +
                  exact_number(o.x + lo.x) + " " + exact_number(o.y + lo.y) + " " +
                  exact_number(o.z + lo.z) + " .. " + exact_number(o.x + hi.x) + " " +
                  exact_number(o.y + hi.y) + " " + exact_number(o.z + hi.z) + ")");
  }
}

}  // namespace treecut::cli
