// treecut build | info | gen
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string_view>

#include "commands.hpp"
#include "progress.hpp"
#include "treecut/attributes.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/generate.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/up_axis.hpp"

namespace treecut::cli {

namespace {

struct ModelArgs {
  std::string model;
  std::string out;
  bool force = false;
  bool real_points = false;
  int k = 12;
};

void print_warning(const std::string& w) {
  std::fprintf(stderr, "warning: %s\n", w.c_str());
}

void add_build_options(CLI::App& cmd, ModelArgs& args) {
  cmd.add_option("-k,--neighbours", args.k,
                 "Neighbours for normals, radii and curvature of point clouds")
      ->check(CLI::Range(3, 64));
  cmd.add_flag(
      "--real-points", args.real_points,
      "Place every parent splat on one of its real points (no splat motion on LOD changes)");
}

OpenOptions open_options(const ModelArgs& args) {
  OpenOptions o;
  o.attributes.k = args.k;
  o.build.parent_at_real_point = args.real_points;
  o.warn = print_warning;
  if (!args.out.empty()) o.cache_path = args.out;
  return o;
}

void print_summary(const std::filesystem::path& model, const OpenedModel& m) {
  const Hierarchy& h = m.hierarchy;
  const glm::vec3 lo = h.bounds_min(), hi = h.bounds_max();
  std::printf("model       %s\n", model.string().c_str());
  std::printf("points      %u\n", h.leaf_count());
  std::printf("nodes       %u\n", h.node_count());
  std::printf("depth       %d\n", h.level_count() - 1);
  std::printf("bounds      [%g %g %g] .. [%g %g %g]\n", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
  const UpAxis up = detect_up_axis(h);  // what `render` and `view` use with --up auto
  std::printf("up          %s (auto: %s)\n", up.name().c_str(), up.reason.c_str());
  std::printf("memory      %.1f MiB (%.1f bytes/point)\n",
              static_cast<double>(h.memory_bytes()) / (1024.0 * 1024.0),
              static_cast<double>(h.memory_bytes()) / std::max(1u, h.leaf_count()));
  // Only a cache that exists is printed as the cache (build fails otherwise).
  if (m.from_cache || m.cache_written)
    std::printf("cache       %s\n", m.cache.string().c_str());
  else
    std::printf("cache       none (not written: %s)\n", m.cache_note.c_str());
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
  const FileKind kind = file_kind(out);
  if (kind == FileKind::Missing) return;
  if (same_file(out, model))
    throw InputError(out.string() + ": is the model itself; refusing to overwrite it with a cache");
  if (kind != FileKind::Regular)
    throw InputError(out.string() + ": is " + std::string(describe(kind)) +
                     "; refusing to write a cache there");
  if (!looks_like_cache(out))
    throw InputError(out.string() +
                     ": exists and is not a treecut cache; refusing to overwrite it");
}

// `gen -o PATH` replaces PATH only when it is a PLY (regenerating a model is
// what gen is for); a directory, a FIFO or any other file is refused.
void check_ply_output(const std::filesystem::path& out) {
  const FileKind kind = file_kind(out);
  if (kind == FileKind::Missing) return;
  if (kind != FileKind::Regular)
    throw InputError(out.string() + ": is " + std::string(describe(kind)) +
                     "; refusing to write a model there");
  bool ply = false;
  try {
    const int fd = open_regular_file(out);
    char magic[4] = {};
    ply = ::read(fd, magic, sizeof magic) == 4 && std::string_view(magic, 4) == "ply\n";
    ::close(fd);
  } catch (const std::exception&) {
    ply = false;
  }
  if (!ply)
    throw InputError(out.string() + ": exists and is not a PLY file; refusing to overwrite it");
}

// `gen --walk PATH` replaces only a camera path (or writes a new file).
void check_walk_output(const std::filesystem::path& out) {
  const FileKind kind = file_kind(out);
  if (kind == FileKind::Missing) return;
  if (kind != FileKind::Regular)
    throw InputError(out.string() + ": is " + std::string(describe(kind)) +
                     "; refusing to write a camera path there");
  bool campath = false;
  try {
    const int fd = open_regular_file(out);
    char head[20] = {};
    campath =
        ::read(fd, head, sizeof head) == 20 && std::string_view(head, 19) == "treecut-camera-path";
    ::close(fd);
  } catch (const std::exception&) {
    campath = false;
  }
  if (!campath)
    throw InputError(out.string() + ": exists and is not a camera path; refusing to overwrite it");
}

}  // namespace

void add_model_commands(CLI::App& app) {
  auto build_args = std::make_shared<ModelArgs>();
  auto* build =
      app.add_subcommand("build", "Build (or refresh) the hierarchy cache of a PLY model");
  // No CLI::ExistingFile: open_model names what MODEL is ("is a FIFO", "is a directory").
  build->add_option("MODEL", build_args->model, "PLY file")->required();
  build->add_option("-o,--output", build_args->out,
                    "Cache file to write (default: the user cache folder)");
  build->add_flag("-f,--force", build_args->force, "Rebuild even when a valid cache exists");
  add_build_options(*build, *build_args);
  build->callback([build_args] {
    OpenOptions o = open_options(*build_args);
    o.use_cache = true;
    // build exists to write the cache: failing to is an error, not a warning.
    o.require_cache = true;
    // -f removes nothing up front: the old cache stays until the new one replaces it.
    o.rebuild = build_args->force;
    require_regular_file(build_args->model);
    if (o.cache_path) check_cache_output(*o.cache_path, build_args->model);
    ProgressBar bar("read");
    o.progress = bar.callback();
    const OpenedModel m = open_model(build_args->model, o);
    bar.finish();
    print_summary(build_args->model, m);
  });

  auto info_args = std::make_shared<ModelArgs>();
  auto* info =
      app.add_subcommand("info", "Summarize a model (PLY, through its cache) or a cache file");
  info->add_option("MODEL", info_args->model, "PLY or .tch cache file")->required();
  add_build_options(*info, *info_args);
  info->callback([info_args] {
    OpenOptions o = open_options(*info_args);
    ProgressBar bar("read");
    o.progress = bar.callback();
    const OpenedModel m = open_model(info_args->model, o);
    bar.finish();
    print_summary(info_args->model, m);
  });

  struct GenArgs {
    std::string kind;
    std::string out;
    std::string source;
    std::string walk;
    std::size_t points = 200000;
    std::uint64_t seed = 1;
  };
  auto gen_args = std::make_shared<GenArgs>();
  auto* gen = app.add_subcommand(
      "gen", "Write a procedural model (sphere, terrain, city, field, plant) as PLY");
  gen->add_option("KIND", gen_args->kind, "sphere | terrain | city | field | plant")->required();
  gen->add_option("-n,--points", gen_args->points, "Number of points")
      ->check(CLI::Range(1ull, 1ull << 31));
  gen->add_option("-o,--output", gen_args->out, "Output PLY (default: assets/KIND.ply)");
  gen->add_option("--seed", gen_args->seed, "Random seed");
  gen->add_option("--source", gen_args->source,
                  "field: the scanned model (PLY) whose copies fill the field");
  gen->add_option("--walk", gen_args->walk,
                  "city, field, plant: also write the scene's walkthrough camera path "
                  "(assets/paths/KIND_walk.campath is made this way)");
  gen->callback([gen_args] {
    const ModelKind kind = parse_model_kind(gen_args->kind);
    if (kind == ModelKind::Field && gen_args->source.empty())
      throw InputError("gen field: needs --source PLY (the model to copy)");
    if (kind != ModelKind::Field && !gen_args->source.empty())
      throw InputError("gen " + gen_args->kind + ": --source is only for field");
    if (!gen_args->walk.empty() && kind != ModelKind::City && kind != ModelKind::Field &&
        kind != ModelKind::Plant)
      throw InputError("gen " + gen_args->kind + ": --walk is only for city, field and plant");
    const std::filesystem::path out =
        gen_args->out.empty() ? std::filesystem::path("assets") / (gen_args->kind + ".ply")
                              : std::filesystem::path(gen_args->out);
    check_ply_output(out);
    if (!gen_args->walk.empty()) check_walk_output(gen_args->walk);
    PointSet source;
    if (kind == ModelKind::Field) {
      require_regular_file(gen_args->source);
      source = load_ply(gen_args->source);
      complete_attributes(source);
    }
    if (out.has_parent_path()) {
      std::error_code ec;
      std::filesystem::create_directories(out.parent_path(), ec);
      if (ec) throw std::runtime_error(system_error_text(out.parent_path(), ec.value()));
    }
    PointSet ps = kind == ModelKind::Field ? generate_field(prepare_field_source(source),
                                                            gen_args->points, gen_args->seed)
                                           : generate_model(kind, gen_args->points, gen_args->seed);
    save_ply(out, ps);
    std::printf("wrote %s (%zu points)\n", out.string().c_str(), ps.size());
    if (!gen_args->walk.empty()) {
      splat::CameraPath path;
      for (const WalkKey& k : scene_walkthrough(kind)) {
        splat::CameraKey key;
        key.time = k.time;
        key.camera.eye = k.eye;
        key.camera.target = k.target;
        key.camera.up = k.up;
        key.camera.fov_y_deg = k.fov_deg;
        path.keys.push_back(key);
      }
      save_camera_path(gen_args->walk, path);
      std::printf("wrote %s (%zu keys, %.1f s)\n", gen_args->walk.c_str(), path.keys.size(),
                  path.duration());
    }
  });
}

}  // namespace treecut::cli
