// The one scene object of the engine (docs/architecture.md, "Vocabulary"):
// an instance of a model placed in the world, as the scene loader makes it,
// the stage carries it, a scene strategy iterates it and the renderer draws
// it; and the stage's scene, the distinct hierarchies with their objects.
// Peng & Cao, "occlusion culling with parallel LOD", section 3.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <memory>
#include <vector>

#include "treecut/hierarchy.hpp"

namespace treecut {

class PagedHierarchy;

/// One object: an instance of a model placed in the world. Plain data,
/// 180 bytes (the memory of one more instance of a model already loaded).
struct SceneObject {
  glm::mat4 world{1.0f};          ///< model -> world (an affine, invertible transform)
  glm::mat4 world_inverse{1.0f};  ///< world -> model
  /// World-space AABB of the model's splat box (its 8 corners transformed):
  /// every splat of the object lies inside.
  glm::vec3 aabb_min{0.0f}, aabb_max{0.0f};
  /// World-space bounding sphere (centre, radius) of every splat: the smaller
  /// of the transformed root sphere and the AABB's circumsphere.
  glm::vec4 sphere{0.0f};
  std::uint32_t model = 0;  ///< index into Scene::models (StageScene::models)
  std::uint32_t file = 0;   ///< index into Scene::files (where the object line is)
  std::uint32_t line = 0;   ///< its line number there
};

/// An object of model `model` placed by `world` (its inverse computed), with
/// no bounds and no place in a file: what a program that places objects
/// itself (tests, benchmarks) hands a StageScene or the renderer, which read
/// only the model and the transforms.
[[nodiscard]] inline SceneObject place_object(std::uint32_t model, const glm::mat4& world) {
  SceneObject o;
  o.model = model;
  o.world = world;
  o.world_inverse = glm::inverse(world);
  return o;
}

/// A scene as the stage carries it: the distinct hierarchies and, per
/// object, which one and its transform. Shared and immutable once handed to
/// a stage (the lists the renderer draws keep it alive, as a model's
/// hierarchy). docs/architecture.md, "Scenes through the stage".
struct StageScene {
  std::vector<std::shared_ptr<const Hierarchy>> models;
  std::vector<SceneObject> objects;  ///< `model` indexes `models`
  /// Per model: its pages when it is drawn from them (models[m] is then its
  /// hierarchy as far as it is resident), else null (held whole). Empty:
  /// every model held whole. The stage's thread alone publishes, asks for
  /// and gives back their pages (paged_hierarchy.hpp).
  std::vector<std::shared_ptr<PagedHierarchy>> paged{};
  /// The hierarchy object `i` draws (its model's, shared by every instance).
  [[nodiscard]] const Hierarchy& hierarchy(std::size_t i) const {
    return *models[objects[i].model];
  }
  /// The sum over objects of their model's node count (what per-object state
  /// costs; a model drawn from its pages: the nodes its memory budget holds).
  [[nodiscard]] std::uint64_t object_nodes() const;
  /// Model M's pages, or null when it is held whole.
  [[nodiscard]] PagedHierarchy* paged_model(std::size_t m) const {
    return m < paged.size() ? paged[m].get() : nullptr;
  }
};

}  // namespace treecut
