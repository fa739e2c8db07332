// treecut build | info | gen

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string_view>

#include "commands.hpp"
#include "messages.hpp"
#include "option_checks.hpp"
#include "output_checks.hpp"
#include "progress.hpp"
#include "survey_command.hpp"
#include "treecut/attributes.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tools/scene_generate.hpp"
#include "treecut/tools/walk_path.hpp"
#include "treecut/up_axis.hpp"

namespace treecut::cli {

namespace {

struct ModelArgs {
  std::string model;
  std::vector<std::string> models;  // build: one model of several files
  std::string out;
  bool force = false;
  bool real_points = false;
  int k = 12;
  std::vector<std::string> columns;
  std::string crs;
  std::uint64_t memory = 0;  // --memory
};

void add_build_options(CLI::App& cmd, ModelArgs& args) {
  add_columns_option(cmd, args.columns);
  add_crs_option(cmd, args.crs);
  add_memory_option(cmd, args.memory);
  cmd.add_option("-k,--neighbours", args.k,
                 "Neighbours for normals, radii and curvature of point clouds")
      ->check(whole_number(3, 64));
  cmd.add_flag(
      "--real-points", args.real_points,
      "Place every parent splat on one of its real points (no splat motion on LOD changes)");
}

OpenOptions open_options(const ModelArgs& args) {
  OpenOptions o;
  o.attributes.k = args.k;
  o.build.parent_at_real_point = args.real_points;
  o.columns = args.columns;
  o.crs = args.crs;
  o.memory = args.memory;
  o.warn = print_warning;
  if (!args.out.empty()) o.cache_path = args.out;
  return o;
}

// Every attribute with its kind and range in the file's values: what
// `--color NAME` and `--classes` can use.
void print_attributes(const Hierarchy& h) {
  if (h.attributes().empty()) {
    std::printf("attributes  none beyond position, normal and colour\n");
    return;
  }
  std::printf("attributes  %zu (colour by one with --color NAME)\n", h.attributes().size());
  for (const NodeAttribute& a : h.attributes()) {
    const bool category = a.kind == AttributeKind::category;
    const char* kind = category ? "category" : "measure";
    const std::string name = one_line(a.name);
    if (std::isnan(a.min)) {
      std::printf("  %-22s %-8s no values\n", name.c_str(), kind);
    } else if (a.min == a.max) {
      std::printf("  %-22s %-8s %s at every point\n", name.c_str(), kind,
                  exact_number(a.min).c_str());
    } else {
      // The file's values, exact (a GPS time keeps its microseconds).
      std::printf("  %-22s %-8s %s .. %s\n", name.c_str(), kind, exact_number(a.min).c_str(),
                  exact_number(a.max).c_str());
    }
  }
}

void print_summary(const std::filesystem::path& model, const OpenedModel& m) {
  const Hierarchy& h = m.hierarchy;
  const glm::vec3 lo = h.bounds_min(), hi = h.bounds_max();
  std::printf("model       %s\n", quoted_name(model).c_str());
  std::printf("points      %u\n", h.leaf_count());
  std::printf("nodes       %u\n", h.node_count());
  std::printf("depth       %d\n", h.level_count() - 1);
  std::printf("bounds      [%g %g %g] .. [%g %g %g]\n", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
  const glm::dvec3 o = h.frame().origin;
  if (o != glm::dvec3(0.0)) {
    // Map coordinates: the nodes are relative to the origin (double), the
    // file's coordinates are origin + bounds.
    std::printf("origin      [%.3f %.3f %.3f] (file coordinates of the model's zero)\n", o.x, o.y,
                o.z);
    std::printf("file bounds [%.3f %.3f %.3f] .. [%.3f %.3f %.3f]\n", o.x + lo.x, o.y + lo.y,
                o.z + lo.z, o.x + hi.x, o.y + hi.y, o.z + hi.z);
  }
  // As the first read said it (cached with the hierarchy).
  if (!h.notes().format.empty())
    std::printf("format      %s\n", one_line(h.notes().format).c_str());
  // The coordinate system, kept in the cache with the origin.
  if (!h.frame().crs.empty()) {
    std::printf("crs         %s\n", one_line(h.frame().crs).c_str());
  } else if (h.notes().format.starts_with("LAS")) {
    std::printf("crs         none in the file\n");
  }
  const UpAxis up = detect_up_axis(h);  // what `render` and `view` use with --up auto
  std::printf("up          %s (auto: %s)\n", up.name().c_str(), up.reason.c_str());
  print_attributes(h);
  std::printf("memory      %.1f MiB (%.1f bytes/point)\n",
              static_cast<double>(h.memory_bytes()) / (1024.0 * 1024.0),
              static_cast<double>(h.memory_bytes()) / std::max(1u, h.leaf_count()));
  // Only a cache that exists is printed as the cache (build fails otherwise).
  if (m.from_cache || m.cache_written)
    std::printf("cache       %s\n", quoted_name(m.cache).c_str());
  else
    std::printf("cache       none (not written: %s)\n", one_line(m.cache_note).c_str());
  if (m.from_cache && m.cache == model) {
    std::printf("loaded      from cache in %.3f s\n", m.cache_seconds);
  } else if (m.from_cache && !m.hashed) {
    // The settled rule (cache.hpp): the model's identity decided, nothing of it was read.
    std::printf("loaded      from cache in %.3f s (model unchanged since the build: not hashed)\n",
                m.cache_seconds);
  } else if (m.from_cache) {
    // The model's content hash runs beside the cache's verification.
    std::printf("loaded      from cache in %.3f s (content hash %.3f s, concurrently%s)\n",
                m.cache_seconds, m.hash_seconds,
                m.cache_refreshed ? "; cache rewritten with the model's identity" : "");
  } else {
    if (m.ply.dropped_nonfinite)
      std::printf("dropped     %zu non-finite points\n", m.ply.dropped_nonfinite);
    std::printf(
        "build time  %.3f s (content hash %.3f, read %.3f, attributes %.3f, hierarchy %.3f, cache "
        "write %.3f)\n",
        m.total_seconds(), m.hash_seconds, m.read_seconds, m.attribute_seconds, m.build_seconds,
        m.cache_seconds);
  }
}

// `build -o PATH` replaces PATH only when it is an earlier cache: never the
// model itself (under any name), another model or any other file of the
// user's, never a directory or a FIFO. Checked before any work, so nothing is
// touched when it is refused.
void check_cache_output(const std::filesystem::path& out, const std::filesystem::path& model) {
  if (same_file(out, model))
    throw InputError(quoted_name(out) +
                     ": is the model itself; refusing to overwrite it with a cache");
  check_replaceable_output(out, is_own_cache, "a cache", "a treecut cache");
}

// `gen -o PATH` (a model), `gen --walk PATH`, `gen city-block | hall -o PATH`.
void check_ply_output(const std::filesystem::path& out) {
  check_replaceable_output(out, is_own_ply, "a model", "a PLY file");
}
void check_walk_output(const std::filesystem::path& out) {
  check_replaceable_output(out, is_own_camera_path, "a camera path", "a camera path");
}
void check_scene_output(const std::filesystem::path& out) {
  check_replaceable_output(out, is_own_scene, "a scene", "a scene file");
}

double mib(std::size_t bytes) {
  return static_cast<double>(bytes) / (1024.0 * 1024.0);
}

void print_scene_summary(const std::filesystem::path& file, const Scene& scene) {
  const SceneMemory mem = scene_memory(scene);
  std::size_t generated = 0;
  for (const auto& m : scene.models)
    generated += m.source.type == SceneModelSource::Type::Generated ? 1 : 0;
  std::printf("scene       %s\n", quoted_name(file).c_str());
  std::printf("objects     %zu\n", scene.objects.size());
  std::printf("models      %zu distinct hierarchies (%zu generated, %zu files)\n",
              scene.models.size(), generated, scene.models.size() - generated);
  std::printf("points      %llu in the objects, %llu in the hierarchies\n",
              static_cast<unsigned long long>(scene.instanced_points()),
              static_cast<unsigned long long>(scene.distinct_points()));
  const glm::vec3 lo = scene.bounds_min, hi = scene.bounds_max;
  std::printf("bounds      [%g %g %g] .. [%g %g %g]\n", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
  if (const glm::dvec3 o = scene.origin; o != glm::dvec3(0.0)) {
    // Georeferenced models stand relative to the first one's origin.
    std::printf("origin      [%.3f %.3f %.3f] (file coordinates of the world's zero)\n", o.x, o.y,
                o.z);
  }
  std::printf("memory      %.1f MiB: hierarchies %.1f MiB, object records %.2f MiB\n",
              mib(mem.hierarchy_bytes + mem.object_bytes), mib(mem.hierarchy_bytes),
              mib(mem.object_bytes));
  std::printf("            %.0f bytes per object, %zu per instance (without sharing: %.1f MiB)\n",
              mem.per_object_bytes(), SceneMemory::per_instance_bytes, mib(mem.unshared_bytes));
  std::printf("loaded      in %.3f s\n", scene.load_seconds);
  for (const auto& m : scene.models)
    std::printf("  %-16s %7u instances %10u points %8.1f MiB  %s%s\n", m.name.c_str(), m.instances,
                m.hierarchy->leaf_count(), mib(m.hierarchy->memory_bytes()),
                m.source.describe().c_str(), m.from_cache ? " (cache)" : "");
}

// `treecut gen city-block | hall`: a scene file (and its walkthrough).
struct SceneGenArgs {
  std::string kind;
  std::filesystem::path out;
  std::vector<std::string> sources;
  std::string walk;
  std::size_t objects = 0;
  std::size_t points = 0;
  std::uint64_t seed = 1;
};

// A model placed by `gen hall`: its path as the scene writes it (relative to
// DIR, the scene's canonical folder), its up axis and its box.
tools::HallSource hall_source(const std::string& s, const std::filesystem::path& dir) {
  // Stood upright by its detected up axis, as `render --up auto` would.
  require_regular_file(s);
  OpenOptions o;
  o.warn = print_warning;
  const OpenedModel m = open_model(s, o);
  tools::HallSource src;
  const std::filesystem::path abs = std::filesystem::weakly_canonical(std::filesystem::absolute(s));
  const std::filesystem::path rel = abs.lexically_relative(dir);
  src.path = rel.empty() ? abs : rel;
  const std::string written = src.path.string();
  if (std::any_of(written.begin(), written.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return u < 0x20 || u == 0x7f || c == ' ' || c == '#';
      }))
    throw InputError(
        quoted_name(s) +
        ": a path with blanks, control characters or '#' cannot be written in a scene file");
  src.up = detect_up_axis(m.hierarchy).vector();
  src.box_min = m.hierarchy.bounds_min();
  src.box_max = m.hierarchy.bounds_max();
  // A model of one point (or all points at one place) has no size to scale
  // into a place of the hall.
  const float magnitude = std::max({1.0f, glm::length(src.box_min), glm::length(src.box_max)});
  if (!(glm::length(src.box_max - src.box_min) > 1e-6f * magnitude))
    throw InputError(quoted_name(s) +
                     ": its points span no volume (a single point, or all at one place); "
                     "nothing to scale into the hall");
  return src;
}

// What `gen` writes must be what treecut reads: within the size of a text
// input, and parsing (LOADABLE: the same scene with absolute model paths).
// Checked before anything is written.
// A scene as this program reads it: `generate` lines of the built-in kinds.
SceneParseOptions scene_parse_options() {
  SceneParseOptions options;
  options.generator = tools::scene_generator();
  return options;
}

void check_scene_loads(const SceneGenArgs& a, const std::string& text,
                       const std::string& loadable) {
  if (text.size() > kTextInputLimit)
    throw InputError(quoted_name(a.out) + ": the scene would be " + std::to_string(text.size()) +
                     " bytes, more than the " + std::to_string(kTextInputLimit) +
                     " a scene file may hold; use fewer --objects");
  try {
    (void)parse_scene_text(loadable, a.out, scene_parse_options());
  } catch (const InputError& e) {
    throw InputError("gen " + a.kind + ": the scene made for " + quoted_name(a.out) +
                     " would not load (" + e.what() + "); nothing written");
  }
}

void generate_scene_file(const SceneGenArgs& a) {
  std::vector<std::pair<std::filesystem::path, std::string>> outputs{{a.out, "the scene (-o)"}};
  if (!a.walk.empty()) outputs.emplace_back(a.walk, "the camera path (--walk)");
  std::vector<std::pair<std::filesystem::path, std::string>> inputs;
  for (const auto& s : a.sources) inputs.emplace_back(s, "a source model (--source)");
  check_distinct_files(outputs, inputs);
  check_scene_output(a.out);
  if (!a.walk.empty()) check_walk_output(a.walk);
  std::string text, loadable;
  std::vector<tools::WalkKey> walk;
  if (a.kind == "city-block") {
    if (!a.sources.empty()) throw InputError("gen city-block: --source is only for field and hall");
    const tools::CityBlockLayout layout = tools::city_block_layout(a.objects, a.seed);
    text = tools::format_city_block_scene(layout, a.seed, a.points);
    loadable = text;
    walk = tools::city_block_walkthrough(layout);
  } else {
    if (a.sources.empty())
      throw InputError("gen hall: needs --source PLY (one or more models to place)");
    // Canonical folder and sources (links resolved): the relative path is
    // then the one the system follows from the scene's folder.
    const std::filesystem::path dir =
        std::filesystem::weakly_canonical(std::filesystem::absolute(a.out).parent_path());
    std::vector<tools::HallSource> sources, absolute_sources;
    for (const auto& s : a.sources) {
      sources.push_back(hall_source(s, dir));
      absolute_sources.push_back(sources.back());
      absolute_sources.back().path =
          std::filesystem::weakly_canonical(std::filesystem::absolute(s));
    }
    const tools::HallLayout layout = tools::hall_layout(a.objects, sources.size(), a.seed);
    text = tools::format_hall_scene(layout, sources, a.seed, a.points);
    // The same scene with absolute paths: it parses before the folder that
    // makes the relative ones resolve exists.
    loadable = tools::format_hall_scene(layout, absolute_sources, a.seed, a.points);
    walk = tools::hall_walkthrough(layout);
  }
  check_scene_loads(a, text, loadable);
  if (a.out.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(a.out.parent_path(), ec);
    if (ec) throw std::runtime_error(system_error_text(a.out.parent_path(), ec.value()));
  }
  write_file_atomically(a.out, text);
  std::printf("wrote %s (%zu objects)\n", quoted_name(a.out).c_str(),
              parse_scene_file(a.out, scene_parse_options()).objects.size());
  if (!a.walk.empty()) {
    const splat::CameraPath path = tools::walk_path(walk);
    save_camera_path(a.walk, path);
    std::printf("wrote %s (%zu keys, %.1f s)\n", quoted_name(a.walk).c_str(), path.keys.size(),
                path.duration());
  }
}

struct GenArgs {
  std::string kind;
  std::string out;
  std::vector<std::string> source;
  std::string walk;
  std::size_t objects = 0;
  std::uint64_t points = 200000;
  std::uint64_t seed = 1;
  std::vector<double> origin;  // --origin X Y Z: where the model sits in file coordinates
  SurveyArgs survey;           // --area, --density, --tile
};

// gen KIND for a scene kind (city-block, hall): the scene file, its models
// generated when it loads. `points_given`: -n was on the command line.
void generate_scene_kind(const GenArgs& g, bool points_given) {
  SceneGenArgs a;
  a.kind = g.kind;
  a.out = g.out.empty() ? std::filesystem::path("assets") / (a.kind + ".scene")
                        : std::filesystem::path(g.out);
  a.sources = g.source;
  a.walk = g.walk;
  a.seed = g.seed;
  // -n is the points of each generated model (buildings, ground tiles).
  a.points = points_given ? g.points : 20000;
  a.objects = g.objects ? g.objects : (a.kind == "hall" ? 1000 : 20000);
  generate_scene_file(a);
}

// gen KIND for a model kind: its options checked, then the PLY (and the
// walkthrough path with --walk) written.
void generate_model_kind(const GenArgs& g) {
  if (g.points > std::uint64_t{1} << 31)
    throw InputError("gen " + g.kind + ": at most 2^31 points (survey writes more, in tiles)");
  if (g.objects) throw InputError("gen " + g.kind + ": --objects is only for city-block and hall");
  if (g.source.size() > 1) throw InputError("gen " + g.kind + ": one --source only");
  const tools::ModelKind kind = tools::parse_model_kind(g.kind);
  if (kind == tools::ModelKind::Field && g.source.empty())
    throw InputError("gen field: needs --source PLY (the model to copy)");
  if (kind != tools::ModelKind::Field && !g.source.empty())
    throw InputError("gen " + g.kind + ": --source is only for field");
  if (!g.walk.empty() && kind != tools::ModelKind::City && kind != tools::ModelKind::Field &&
      kind != tools::ModelKind::Plant)
    throw InputError("gen " + g.kind + ": --walk is only for city, field and plant");
  const std::filesystem::path out = g.out.empty()
                                        ? std::filesystem::path("assets") / (g.kind + ".ply")
                                        : std::filesystem::path(g.out);
  std::vector<std::pair<std::filesystem::path, std::string>> outputs{{out, "the model (-o)"}};
  if (!g.walk.empty()) outputs.emplace_back(g.walk, "the camera path (--walk)");
  std::vector<std::pair<std::filesystem::path, std::string>> inputs;
  for (const auto& s : g.source) inputs.emplace_back(s, "the source scan (--source)");
  check_distinct_files(outputs, inputs);
  // The format by the name: .las writes LAS, .pcd PCD, anything else PLY
  // (each with double coordinates where the model has an origin).
  const bool las = out.extension() == ".las" || out.extension() == ".LAS";
  const bool pcd = out.extension() == ".pcd" || out.extension() == ".PCD";
  if (las) {
    check_replaceable_output(out, is_own_las, "a model", "a LAS file");
  } else if (pcd) {
    check_replaceable_output(out, is_own_pcd, "a model", "a PCD file");
  } else {
    check_ply_output(out);
  }
  if (!g.walk.empty()) check_walk_output(g.walk);
  PointSet source;
  if (kind == tools::ModelKind::Field) {
    require_regular_file(g.source.front());
    source = load_ply(g.source.front());
    complete_attributes(source);
  }
  if (out.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(out.parent_path(), ec);
    if (ec) throw std::runtime_error(system_error_text(out.parent_path(), ec.value()));
  }
  PointSet ps = kind == tools::ModelKind::Field
                    ? tools::generate_field(tools::prepare_field_source(source), g.points, g.seed)
                    : tools::generate_model(kind, g.points, g.seed);
  if (!g.origin.empty()) ps.frame.origin = glm::dvec3(g.origin[0], g.origin[1], g.origin[2]);
  if (las || pcd) tools::add_survey_attributes(ps, kind);
  if (las) {
    save_las(out, ps);
  } else if (pcd) {
    save_pcd(out, ps);
  } else {
    save_ply(out, ps);
  }
  std::printf("wrote %s (%zu points)\n", quoted_name(out).c_str(), ps.size());
  if (!g.walk.empty()) {
    const splat::CameraPath path = tools::walk_path(tools::scene_walkthrough(kind));
    save_camera_path(g.walk, path);
    std::printf("wrote %s (%zu keys, %.1f s)\n", quoted_name(g.walk).c_str(), path.keys.size(),
                path.duration());
  }
}

// What `build` takes: a point file, a folder of them or several files (one
// model: issue 44), each checked to be one before any work.
std::vector<std::filesystem::path> build_inputs(const std::vector<std::string>& models) {
  std::vector<std::filesystem::path> files(models.begin(), models.end());
  for (const std::filesystem::path& f : files) {
    std::error_code ec;
    if (files.size() == 1 && std::filesystem::is_directory(f, ec)) break;
    require_regular_file(f);
    if (looks_like_cache(f))
      throw InputError(
          quoted_name(f) +
          ": is a treecut cache already; build takes a point file, several or a folder of them "
          "(info shows the cache)");
  }
  return files;
}

void add_build_command(CLI::App& app) {
  auto build_args = std::make_shared<ModelArgs>();
  auto* build = app.add_subcommand(
      "build",
      "Build (or refresh) the hierarchy cache of a point file (PLY, LAS, PCD, text), or of "
      "several files or a folder of them as one model");
  // No CLI::ExistingFile: open_model names what MODEL is ("is a FIFO", "is a directory").
  build
      ->add_option("MODEL", build_args->models,
                   "The point file (PLY, LAS, PCD, XYZ, PTS, CSV); several files, or a folder "
                   "of them, are one model (a survey's tiles, sharing a coordinate system)")
      ->check(non_empty_path())
      ->required();
  build
      ->add_option("-o,--output", build_args->out,
                   "Cache file to write (default: the user cache folder)")
      ->check(non_empty_path());
  build->add_flag("-f,--force", build_args->force, "Rebuild even when a valid cache exists");
  add_build_options(*build, *build_args);
  build->callback([build_args] {
    OpenOptions o = open_options(*build_args);
    o.use_cache = true;
    // build exists to write the cache: failing to is an error, not a warning.
    o.require_cache = true;
    // -f removes nothing up front: the old cache stays until the new one replaces it.
    o.rebuild = build_args->force;
    const std::vector<std::filesystem::path> files = build_inputs(build_args->models);
    if (o.cache_path) {
      for (const std::filesystem::path& f : files) check_cache_output(*o.cache_path, f);
    }
    ProgressBar bar("read");
    o.progress = bar.callback();
    const OpenedModel m = open_model(files, o);
    bar.finish();
    print_summary(files.size() == 1
                      ? files.front()
                      : std::filesystem::path(files.front().string() + " and " +
                                              std::to_string(files.size() - 1) + " more"),
                  m);
  });
}

void add_info_command(CLI::App& app) {
  auto info_args = std::make_shared<ModelArgs>();
  auto* info = app.add_subcommand(
      "info", "Summarize a point file (through its cache), a cache file or a scene");
  info->add_option("MODEL", info_args->model,
                   "A point file (PLY, LAS, PCD, XYZ, PTS, CSV), a .tch cache or a .scene")
      ->check(non_empty_path())
      ->required();
  add_build_options(*info, *info_args);
  info->callback([info_args] {
    OpenOptions o = open_options(*info_args);
    if (looks_like_scene(info_args->model)) {
      SceneLoadOptions so;
      so.parse = scene_parse_options();
      so.open = o;
      print_scene_summary(info_args->model, load_scene(info_args->model, so));
      return;
    }
    ProgressBar bar("read");
    o.progress = bar.callback();
    const OpenedModel m = open_model(info_args->model, o);
    bar.finish();
    print_summary(info_args->model, m);
  });
}

void add_gen_command(CLI::App& app) {
  auto gen_args = std::make_shared<GenArgs>();
  auto* gen = app.add_subcommand(
      "gen",
      "Write a procedural model (sphere, terrain, city, field, plant) as PLY, a scene "
      "(city-block, hall) as a scene file, or a survey's LAS tiles into a folder");
  gen->add_option("KIND", gen_args->kind,
                  "sphere | terrain | city | field | plant | city-block | hall | survey")
      ->required();
  gen->add_option("-n,--points", gen_args->points,
                  "Number of points (city-block, hall: of each generated model, default 20000)")
      ->check(whole_number(1, std::uint64_t{1} << 40));
  gen->add_option("-o,--output", gen_args->out,
                  "Output PLY, LAS when it ends in .las, PCD (binary_compressed) in .pcd (default: "
                  "assets/KIND.ply; a scene: "
                  "assets/KIND.scene)")
      ->check(non_empty_path());
  gen->add_option("--origin", gen_args->origin,
                  "X Y Z: place the model there in file coordinates (map coordinates such as "
                  "500000 5000000 0)")
      ->expected(3)
      ->check(finite_number(-1e9, 1e9));
  gen->add_option("--seed", gen_args->seed, "Random seed")
      ->check(whole_number(0, std::numeric_limits<std::uint64_t>::max()));
  gen->add_option("--source", gen_args->source,
                  "field: the scanned model (PLY) whose copies fill the field; hall: the models "
                  "to place (repeat the option for several)")
      ->check(non_empty_path());
  gen->add_option("--objects", gen_args->objects,
                  "city-block (default 20000 buildings), hall (default 1000 copies): objects")
      ->check(whole_number(1, kMaxSceneObjects / 2));
  gen->add_option(
         "--walk", gen_args->walk,
         "city, field, plant, city-block, hall: also write the scene's walkthrough camera path "
         "(assets/paths/KIND_walk.campath is made this way)")
      ->check(non_empty_path());
  gen->add_option("--area", gen_args->survey.area,
                  "survey: W H, the area east and north in km (default: a square of -n points at "
                  "the density, else 1 x 1)")
      ->expected(2)
      ->check(finite_number(0.001, 1e4));
  gen->add_option("--density", gen_args->survey.density,
                  "survey: returns per square metre (default 8; with -n and --area, -n decides)")
      ->check(finite_number(0.01, 1e4));
  gen->add_option("--tile", gen_args->survey.tile, "survey: tile edge in metres (default 500)")
      ->check(finite_number(1.0, 1e5));
  gen->callback([gen_args, gen] {
    const bool survey = gen_args->kind == "survey";
    for (const char* o : {"--area", "--density", "--tile"}) {
      if (!survey && gen->count(o) != 0)
        throw InputError("gen " + gen_args->kind + ": " + o + " is only for survey");
    }
    if (survey) {
      if (!gen_args->source.empty() || !gen_args->walk.empty() || gen_args->objects != 0)
        throw InputError("gen survey: --source, --walk and --objects are not for a survey");
      generate_survey(gen_args->survey, gen_args->out,
                      gen->count("--points") != 0 ? gen_args->points : 0, gen_args->seed,
                      gen_args->origin);
      return;
    }
    if (gen_args->kind == "city-block" || gen_args->kind == "hall") {
      generate_scene_kind(*gen_args, gen->count("--points") != 0);
      return;
    }
    generate_model_kind(*gen_args);
  });
}

}  // namespace

void add_model_commands(CLI::App& app) {
  add_build_command(app);
  add_info_command(app);
  add_gen_command(app);
}

}  // namespace treecut::cli
