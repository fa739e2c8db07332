// Scenes of many objects (issue 13; Peng & Cao, "occlusion culling with
// parallel LOD", section 3: "a complex 3D environment model consists of many
// disconnected objects"): a scene file lists models and objects, each object
// an instance of a model with a world transform. Instances of one model share
// one Hierarchy, built (or mapped from its cache) once. Format and rules:
// docs/scene-files.md.
//
// What the later stages take from here: the union cut of a scene is one
// TreeCut per distinct model's hierarchy per object (SceneObject::model says
// which), the renderer's pooled vertex buffer holds each distinct hierarchy
// once (SceneModel is the unit of upload) and draws an object's cut with its
// `world` matrix; culling and the budget (Eq. 1) read the world AABB, the
// bounding sphere and the model's point count of every object.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <glm/ext/vector_double3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/hierarchy.hpp"
#include "treecut/model_io.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/scene_object.hpp"

namespace treecut {

/// The header line of a scene file (version 1).
inline constexpr std::string_view kSceneHeader = "treecut-scene 1";
/// At most this many objects in a scene, includes counted (a line per object
/// is 180 bytes loaded, SceneObject; a million objects are 180 MB).
inline constexpr std::size_t kMaxSceneObjects = std::size_t{1} << 20;
/// Includes nest at most this deep (a cycle is reported as a cycle before).
inline constexpr int kMaxSceneIncludeDepth = 16;
/// A generated model has at most this many points (as `treecut gen -n`).
inline constexpr std::uint64_t kMaxGeneratedPoints = std::uint64_t{1} << 31;

/// Where a model comes from: a file (PLY or .tch, through the cache) or a
/// generator with a seed and a point count.
struct SceneModelSource {
  enum class Type { File, Generated } type = Type::File;
  std::filesystem::path file;  ///< File: the path (relative ones resolved against the scene file)
  std::string kind;            ///< Generated: one of SceneGenerator::kinds
  std::uint64_t seed = 0;
  std::uint64_t points = 0;
  /// "FILE" or "KIND seed S points N", for messages and summaries.
  [[nodiscard]] std::string describe() const;
};

/// One distinct hierarchy of a scene: what every instance of it shares.
struct SceneModel {
  std::string name;  ///< the name of its first declaration
  SceneModelSource source;
  std::string declared_at;  ///< "FILE:LINE" of that declaration
  /// Shared and immutable (Model::hierarchy takes it as is).
  std::shared_ptr<const Hierarchy> hierarchy;
  /// Model-space box around every splat: the points' bounds grown by the
  /// largest leaf splat radius.
  glm::vec3 box_min{0.0f}, box_max{0.0f};
  std::uint32_t instances = 0;  ///< objects that use it
  bool from_cache = false;      ///< a file model mapped from its cache
  /// A cache drawn from its pages (SceneLoadOptions::paging): `hierarchy`
  /// is its hierarchy as far as it is resident; null for a model held whole.
  std::shared_ptr<PagedHierarchy> paged;
};

struct Scene {
  std::vector<std::filesystem::path> files;      ///< the scene file, then each included file
  std::vector<SceneModel> models;                ///< distinct hierarchies, in order of first use
  std::vector<SceneObject> objects;              ///< in file order (includes where they stand)
  glm::vec3 bounds_min{0.0f}, bounds_max{0.0f};  ///< union of the objects' AABBs
  double load_seconds = 0.0;                     ///< wall time of load_scene's model loads
  /// The file coordinates of the world's zero (map coordinates): the origin
  /// of the first model that has one (Hierarchy::frame(), e.g. a LAS), else
  /// 0. A model with an origin O is placed at O - origin after its object's
  /// transform, so georeferenced models (LAS tiles) stand where their files
  /// put them relative to each other; models without one (PLY, generated)
  /// stay where the scene file puts them.
  glm::dvec3 origin{0.0};

  /// Points drawn at full detail: the sum over objects of their model's points.
  [[nodiscard]] std::uint64_t instanced_points() const;
  /// Points held: the sum over distinct models.
  [[nodiscard]] std::uint64_t distinct_points() const;
  /// "FILE:LINE" of an object's line.
  [[nodiscard]] std::string where(const SceneObject& object) const;
};

/// The singular values of the linear part of an object's affine transform,
/// largest first: how much it stretches a length at most and at least (a
/// sphere of radius r becomes an ellipsoid with these semi-axes times r).
/// Square roots of the eigenvalues of L^T L in double, closed form for a
/// symmetric 3x3 (Smith 1961); exactly 1, 1, 1 for the identity.
std::array<double, 3> singular_values(const glm::mat4& world);

/// Whether the linear part of a transform is safely invertible: finite, no
/// column shorter than 1e-30, and its determinant neither lost in rounding
/// relative to the product of the column lengths (1e-9: a singular matrix
/// written with rounded numbers) nor relative to the longest column cubed
/// (1e-12: a flattening whose inverse and normal widening leave floats).
/// The one test: the scene parser rejects what fails it (FILE:LINE, exit 2),
/// and the scene drawer asserts it.
bool invertible_transform(const glm::dmat3& linear);

/// The memory of a loaded scene (what `treecut info` and the benchmarks print).
struct SceneMemory {
  std::size_t hierarchy_bytes = 0;  ///< node arrays of the distinct hierarchies, each once
  std::size_t object_bytes = 0;     ///< the object records
  std::size_t unshared_bytes = 0;   ///< hierarchy bytes if every object had its own copy
  std::size_t objects = 0;
  /// One more instance of a loaded model: its object record.
  static constexpr std::size_t per_instance_bytes = sizeof(SceneObject);
  /// Everything divided by the objects: hierarchies and records.
  [[nodiscard]] double per_object_bytes() const;
};
SceneMemory scene_memory(const Scene& scene);

// ---------------------------------------------------------------------------
// Parsing (no model is read; the files a model line names must exist).

/// A model declaration as parsed.
struct SceneModelDecl {
  std::string name;
  SceneModelSource source;
  std::uint32_t file = 0, line = 0;
};
struct SceneDescription {
  std::vector<std::filesystem::path> files;
  std::vector<SceneModelDecl> models;  ///< every declaration, includes' too
  /// The object lines as parsed: transform, file and line, and `model` the
  /// index of its declaration in `models` (load_scene maps declarations to
  /// distinct models and fills the bounds).
  std::vector<SceneObject> objects;
};

/// What makes the models of a scene's `generate NAME KIND SEED POINTS` lines.
/// The core reads scene files but makes no procedural content: a program
/// passes treecut::tools::scene_generator() (treecut/tools/scene_generate.hpp)
/// for the built-in kinds, or its own. Without one, every `generate` line is
/// an unknown kind (FILE:LINE).
struct SceneGenerator {
  std::vector<std::string> kinds;  ///< the KIND names a scene may use
  /// Exactly POINTS points of KIND (one of `kinds`), deterministic for a seed;
  /// called from several threads at once.
  std::function<PointSet(std::string_view kind, std::size_t points, std::uint64_t seed)> make;
};

struct SceneParseOptions {
  std::size_t max_objects = kMaxSceneObjects;
  SceneGenerator generator;
};

/// Parses FILE and what it includes. Throws InputError "FILE:LINE: REASON"
/// for any malformed line (docs/scene-files.md lists them), "FILE: REASON"
/// for a file that cannot be read or a scene without objects.
SceneDescription parse_scene_file(const std::filesystem::path& file,
                                  const SceneParseOptions& options = {});

/// Parses TEXT as the scene file NAME (relative paths resolve against NAME's
/// folder). For tests and fuzzing; includes are read from disk.
SceneDescription parse_scene_text(std::string_view text, const std::filesystem::path& name,
                                  const SceneParseOptions& options = {});

// ---------------------------------------------------------------------------
// Loading.

struct SceneLoadOptions {
  SceneParseOptions parse;
  /// How file models are opened (cache, attributes, build options). Its
  /// `warn` may be called from several threads at once (load_scene
  /// serializes the calls); its `progress` is not used.
  OpenOptions open;
  /// Threads that load distinct models at once; 0 = hardware threads.
  unsigned threads = 0;
  /// Set: the models that are caches (.tch) are drawn from their pages
  /// (issue 45), not held whole, within memory_bytes shared among them in
  /// proportion to their files' sizes (each at least what its first page
  /// and largest group of pages take); node_limit likewise. Other models
  /// are loaded whole.
  std::optional<PagingOptions> paging;
};

/// Parses FILE and loads every distinct model once, several at a time:
/// objects naming the same file (the same device and inode, whatever the
/// path or declaration) or the same generated kind, seed and point count
/// share one Hierarchy. A model that fails to load is an error naming the
/// line that declared it ("FILE:LINE: model NAME: REASON"), an InputError when
/// the model is malformed, std::runtime_error otherwise.
Scene load_scene(const std::filesystem::path& file, const SceneLoadOptions& options = {});

/// Whether PATH looks like a scene file: its name ends in ".scene" or it
/// starts with "treecut-scene". Never blocks (a FIFO is not one).
bool looks_like_scene(const std::filesystem::path& path);

}  // namespace treecut
