// Shared pieces of `treecut render` (headless) and `treecut view` (window):
// model and strategy set-up from the command line and the viewer entry point.
// The frame itself runs in the library (treecut/splat/frame.hpp).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "treecut/controller.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/registry.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/coloring.hpp"
#include "treecut/splat/node_pool.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tree_cut.hpp"
#include "treecut/up_axis.hpp"

// CLI11 is declared, not included: it costs every viewer file about 6 s of
// compile time and only the command files build options.
namespace CLI {
class App;
}

namespace treecut::cli {

/// Options common to render and view.
struct SceneArgs {
  std::string model;  ///< PLY or .tch; empty = the generated default model
  std::string default_kind = "terrain";
  std::size_t default_points = 200000;
  std::vector<std::string> strategies{"optimization"};
  std::vector<std::string> params;  ///< "name=value"
  std::vector<std::string> plugins;
  std::string mode = "fast";
  float radius_scale = 1.0f;
  float point_size = 2.0f;
  int k = 12;
  bool fixed_light = false;
  bool unlit = false;                ///< --unlit: the file's colours, unshaded
  std::string up = "auto";           ///< x | y | z | auto (from the data: treecut/up_axis.hpp)
  bool validate = false;             ///< --validate: check every cut a strategy returns in full
  int stage_wait_bound_ms = 100;     ///< raise a starved stage after this wait; 0 = never
  unsigned blend_frames = 0;         ///< --blend N: exchanges fade over N frames (0 = swap)
  std::string color = "auto";        ///< --color auto | rgb | elevation | ATTRIBUTE
  std::string color_map = "auto";    ///< --color-map auto | viridis | grey | classes
  std::vector<double> color_range;   ///< --color-range LOW HIGH (the file's values)
  std::string classes;               ///< --classes 2,6 | -7,-18
  std::vector<std::string> columns;  ///< --columns: a text cloud's columns
  std::string crs;                   ///< --crs: the coordinate system to draw in
  std::uint64_t memory = 0;          ///< --memory: the bytes a build may use
  std::uint64_t gpu_memory = 0;      ///< --gpu-memory: a paged model's pool (0: its default)
  std::uint64_t gpu_upload = std::uint64_t{8} << 20;  ///< --gpu-upload: bytes a frame
  double stall_timeout_s = 15.0;  ///< --stall-timeout: a URL's read receiving nothing fails
  std::string edl = "auto";       ///< --edl auto | on | off: eye-dome lighting
  float edl_strength = 0.25f;     ///< --edl-strength
  std::vector<double> clip;       ///< --clip X0 Y0 Z0 X1 Y1 Z1 (file coordinates)
};

void add_scene_options(CLI::App& cmd, SceneArgs& args);

struct Scene {
  std::shared_ptr<const Hierarchy> hierarchy;
  std::string label;  ///< file name or "generated terrain (200000 points)"
  glm::vec3 center{0.0f};

  float radius = 1.0f;
  glm::vec3 up{0.0f, 1.0f, 0.0f};  ///< the model's up axis (orbits turn about it)
  UpAxis up_axis;                  ///< the same, named; reason set when --up auto chose it
  glm::vec3 bounds_min{0.0f}, bounds_max{0.0f};  ///< the model's, or the scene's (Scene::bounds)
  /// The box the first view and the orbits fit (issue 43, item 12): the
  /// bounds with a typical splat's reach on every side and at least 8 splats
  /// across, so a lone point is a dot and ten points on a line fit the
  /// frame, discs and all.
  glm::vec3 view_min{0.0f}, view_max{0.0f};
  /// Where the first view opens when the file says where its sensor stood
  /// (a depth camera's PCD VIEWPOINT), as PCL's viewer opens it.
  std::optional<splat::Camera> sensor_view;
  /// A scene file (looks_like_scene): its objects for the stage; `hierarchy`
  /// is then its first model's. Null for a model.
  std::shared_ptr<const StageScene> world;
  std::uint64_t instanced_points = 0;  ///< a scene: points of all objects at full detail
  /// A cache drawn from its pages (a .tch with --memory: issue 45);
  /// `hierarchy` is then its hierarchy(). Null for a model held whole.
  std::shared_ptr<PagedHierarchy> paged;
};

/// The models of SCENE drawn from their pages: the model's, or a scene's
/// (those of its models that are caches, with --memory). Empty: all whole.
std::vector<PagedHierarchy*> paged_models(const Scene& scene);
/// A scene's models as its GPU pool holds them (a cache's pages, the others
/// whole); empty for a scene held whole or a single model.
std::vector<splat::PoolModel> pool_models(const Scene& scene);

/// A paged model's GPU pool as --gpu-memory and --gpu-upload say.
splat::GpuPoolOptions gpu_pool_options(const SceneArgs& args);
/// The vertices the renderer's pool for SCENE starts with (0: a model held
/// whole); InputError naming the model when --gpu-memory is too small.
std::uint32_t pool_vertices(const Scene& scene, const SceneArgs& args);

/// Opens the model (through its cache) or generates the default one, or
/// loads a scene file (treecut::load_scene: the camera fits Scene::bounds,
/// up is +z unless --up says otherwise). Throws InputError for a bad model
/// or scene file.
Scene load_scene(const SceneArgs& args);
/// The same, reporting the stages of opening a model file (OpenOptions::progress:
/// "read", "attributes", "hierarchy", "cache"; on the calling thread).
using LoadProgressFn = std::function<void(std::string_view stage, std::size_t, std::size_t)>;
Scene load_scene(const SceneArgs& args, const LoadProgressFn& progress);

/// The cut a model opens with in `view` (issue 30; `render` starts at the
/// root, as its tables and a scene's objects do): a
/// breadth-first cut of 20,000 nodes (or all leaves), uniform and at once,
/// not the root's handful of discs the size of the model that the first
/// frames showed until the strategy had refined them.
TreeCut opening_cut(const Hierarchy& h);

/// The built-in strategies plus the plugins named in `args`.
StrategyRegistry make_registry(const SceneArgs& args);

/// Parses "name=value"; throws InputError.
std::pair<std::string, double> parse_param(const std::string& text);

/// A strategy with those of `params` ("name=value") applied that it has;
/// values out of range are an InputError.
std::unique_ptr<Strategy> make_strategy(const StrategyRegistry& registry, const std::string& name,
                                        const std::vector<std::string>& params);
/// Applies those of `params` ("name=value") that `strategy` has.
void apply_params(Strategy& strategy, const std::vector<std::string>& params);

/// Throws InputError for an unknown strategy, a parameter no selected strategy
/// has, or a value out of range.
void check_params(const StrategyRegistry& registry, const std::vector<std::string>& strategies,
                  const std::vector<std::string>& params);

splat::RenderSettings render_settings(const SceneArgs& args);

/// What of the render settings depends on the model: eye-dome lighting
/// (--edl on, or auto and a model whose normals were estimated: no normals
/// in the file, a LAS, most text and PCD clouds, shading by them being a
/// guess) and the --clip box (file coordinates, the model's origin taken
/// off in double; a scene's world coordinates).
void apply_model_settings(splat::RenderSettings& settings, const SceneArgs& args,
                          const Scene& scene);

/// The clip box X0 Y0 Z0 X1 Y1 Z1 (file coordinates; none when `box` is
/// empty) into `settings` for `scene` (--clip, a script's `clip`).
void apply_clip(splat::RenderSettings& settings, const std::vector<double>& box,
                const Scene& scene);

/// --color, --color-map, --color-range and --classes as a ColorBy; throws
/// InputError for a bad map, range or class list.
splat::ColorBy color_by(const SceneArgs& args);
/// color_by() for SCENE's model, --color auto resolved
/// (splat::resolve_auto_color), *NOTE saying what auto chose where the
/// file's RGB was not usable.
splat::ColorBy resolve_color(const Scene& scene, const SceneArgs& args, std::string* note);
/// Colours every model of SCENE by BY in RENDERER (Renderer::set_node_colors;
/// the models' own colours for plain rgb without a class filter). Returns
/// the first model's legend. Throws InputError for an attribute a model
/// lacks.
splat::Legend apply_coloring(const Scene& scene, const splat::ColorBy& by,
                             splat::Renderer& renderer);
/// Throws the InputError apply_coloring would, before anything is drawn.
void check_coloring(const Scene& scene, const splat::ColorBy& by);
/// One line for a report: "intensity: viridis from 12 to 480" or
/// "classification: 2 ground 61 %, 6 building 20 %, ...".
std::string legend_line(const splat::Legend& legend);

/// The stage options `render` and `view` share: --validate, and a bounded exit
/// when a strategy ignores cancellation at shutdown (one error line, exit 1).
void configure_stage(StageOptions& options, const SceneArgs& args);

/// One warning line when the stage fell behind during a run (no iteration at
/// all, or requests that waited past the starvation bound); else empty.
std::string stage_shortfall(const std::string& strategy, const StageCounters& counters,
                            const StageOptions& options, int frames);

struct ViewArgs {
  SceneArgs scene;
  int width = 1280;
  int height = 720;
  std::string path;    ///< replay this camera path, then keep running (or exit with script)
  std::string script;  ///< scripted run: see docs/camera-paths.md
  std::string screenshot_dir = ".";
  /// > 0: adapt the strategy's budget to hold this rate. 30 by default
  /// (issue 30): the budget grows to full detail where the machine draws it
  /// at that rate, and shrinks where it cannot.
  double target_fps = 30.0;
  /// Further models (`treecut view A B C`): the O key cycles through all of them.
  std::vector<std::string> more_models;
};

/// Runs the window until it is closed (or the script ends). Returns an exit code.
int run_viewer(const ViewArgs& args);

}  // namespace treecut::cli
