// treecut build | info (gen: gen_command.cpp)

#include <sys/resource.h>

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
// The cache's pages from its table alone (issue 44): how many, how large.
void print_cache_pages(const std::filesystem::path& cache, const Hierarchy& h) {
  std::string why;
  const std::optional<std::vector<CachePage>> pages = read_cache_pages(cache, &why);
  if (!pages) return;  // rewritten since it was read: the next open says so
  std::uint64_t bytes = 0;
  std::uint32_t largest = 0;
  for (const CachePage& p : *pages) bytes += p.bytes, largest = std::max(largest, p.nodes);
  std::printf("pages       %zu (largest %u nodes), %.1f MiB (%.1f bytes/point)\n", pages->size(),
              largest, double(bytes) / (1024.0 * 1024.0),
              double(bytes) / double(std::max(1u, h.leaf_count())));
}

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

double mib(std::size_t bytes) {
  return static_cast<double>(bytes) / (1024.0 * 1024.0);
}

// How a build in chunks went (issue 44): the chunks, their halo, the
// memory and temporary disk it took.
void print_chunks(const OpenedModel& m) {
  const ChunkedBuildFigures& c = m.chunked;
  struct rusage usage {};
  ::getrusage(RUSAGE_SELF, &usage);
  std::printf(
      "chunks      %zu, %u at a time, the largest %llu points with its halo (halo %.3g units, "
      "%.1f %% of the points copied into it)\n",
      c.chunks, c.lanes, static_cast<unsigned long long>(c.largest_chunk), double(c.halo),
      100.0 * double(c.halo_points) / double(std::max<std::size_t>(m.input_points, 1)));
  std::printf(
      "memory      peak %.1f MiB of a budget of %.1f MiB; temporary disk at most %.1f MiB\n",
      double(usage.ru_maxrss) / 1024.0, mib(c.budget), mib(c.scratch_bytes));
}

// A model built in chunks whose hierarchy is larger than the memory budget
// is not loaded: its cache is what there is to say.
void print_unloaded(const std::filesystem::path& model, const OpenedModel& m) {
  std::printf("model       %s\n", quoted_name(model).c_str());
  std::printf("points      %zu\n", m.input_points);
  print_chunks(m);
  std::printf("cache       %s\n", quoted_name(m.cache).c_str());
  std::string why;
  if (const auto pages = read_cache_pages(m.cache, &why)) {
    std::uint64_t bytes = 0, nodes = 0;
    for (const CachePage& p : *pages) bytes += p.bytes, nodes += p.nodes;
    std::printf("pages       %zu, %llu nodes, %.1f MiB (%.1f bytes/point)\n", pages->size(),
                static_cast<unsigned long long>(nodes), mib(bytes),
                double(bytes) / double(std::max<std::size_t>(m.input_points, 1)));
  }
  std::printf("not loaded  the hierarchy is larger than the memory budget (info loads it)\n");
  std::printf(
      "build time  %.3f s (content hash %.3f, read %.3f, attributes %.3f, hierarchy %.3f, cache "
      "write %.3f)\n",
      m.total_seconds(), m.hash_seconds, m.read_seconds, m.attribute_seconds, m.build_seconds,
      m.cache_seconds);
}

void print_summary(const std::filesystem::path& model, const OpenedModel& m) {
  if (m.hierarchy.empty()) return print_unloaded(model, m);
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
  if (m.chunked.chunks) print_chunks(m);
  // Only a cache that exists is printed as the cache (build fails otherwise).
  if (m.from_cache || m.cache_written) {
    std::printf("cache       %s\n", quoted_name(m.cache).c_str());
    print_cache_pages(m.cache, h);
  } else
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
    o.need_hierarchy = false;  // a model built in chunks past the budget stays in its cache
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
      so.parse.generator = tools::scene_generator();
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

}  // namespace

void add_model_commands(CLI::App& app) {
  add_build_command(app);
  add_info_command(app);
  add_gen_command(app);  // gen_command.cpp
}

}  // namespace treecut::cli
