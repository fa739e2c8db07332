// treecut gen: procedural models (tools/generate.hpp) as PLY, LAS or PCD,
// scenes of them (city-block, hall) and a survey's LAS tiles
// (survey_command.cpp).

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.hpp"
#include "messages.hpp"
#include "option_checks.hpp"
#include "output_checks.hpp"
#include "survey_command.hpp"
#include "treecut/attributes.hpp"
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

}  // namespace

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

}  // namespace treecut::cli
