// A scene's cut on the GPU: the cuts of many objects, each an instance of one
// of a few hierarchies with its own transform, drawn in one call per pass
// (issue 13; Peng & Cao, "occlusion culling with parallel LOD selection",
// draw their city of objects the same way: the geometry of each distinct
// model once, the objects as instances of it).
//
// - The models: Renderer::set_models puts every distinct hierarchy's nodes in
//   the one vertex buffer, model i from model_base(i) on.
// - The objects: a record per object (its model -> world matrix and what a
//   splat needs of it, ObjectRecord), uploaded once per scene, read by the
//   vertex stage as an instanced attribute.
// - The cut: per object an index list of its model's node ids; the lists lie
//   back to back in one element buffer and each non-empty one is a command
//   of glMultiDrawElementsIndirect (count, firstIndex = where its list
//   starts, baseVertex = its model's base, baseInstance = the object, so the
//   instanced attribute reads its record). The draw calls per frame do not
//   grow with the objects: one per pass.
//
// All methods: render thread only, with the renderer's context current.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>
#include <span>
#include <vector>

#include "treecut/hierarchy.hpp"
#include "treecut/scene_object.hpp"
#include "treecut/splat/gl_objects.hpp"

namespace treecut::splat {

class Renderer;
class VertexMap;

/// Objects a SceneCutBuffer takes: their index is a float in the object
/// record, exact below 2^24, and 0xffffff is the ObjectId mode's background.
inline constexpr std::size_t kMaxSceneDrawObjects = std::size_t{1} << 24;

/// What the vertex stage reads per object (shaders.hpp, kObjectVertex):
/// rows 0-2 of the affine model -> world matrix and `extra` = (sigma, cone
/// widening, sign of the determinant, the object's index: 0 from
/// object_record, set by SceneCutBuffer::set_objects). sigma is the largest singular value
/// of the linear part (a splat of radius r covers its transformed disc at
/// radius sigma r); the widening bounds how much the sine of a normal cone's
/// half-angle grows (sigma_1 sigma_2 / sigma_3^2; exactly 1 for a
/// similarity, whose cones keep their angle).
struct ObjectRecord {
  glm::vec4 row0{1, 0, 0, 0};
  glm::vec4 row1{0, 1, 0, 0};
  glm::vec4 row2{0, 0, 1, 0};
  glm::vec4 extra{1, 1, 1, 0};
};
static_assert(sizeof(ObjectRecord) == 64);

/// The record of `world`; the identity gives the identity record exactly (a
/// single model draws as before, bit for bit). Throws std::invalid_argument
/// for a matrix that is not affine (last row 0 0 0 1), not finite or not
/// invertible.
ObjectRecord object_record(const glm::mat4& world);

/// The element and command buffers of a scene's cut, and its objects' records.
class SceneCutBuffer {
 public:
  /// The objects, in the order upload() takes their cuts, for the models
  /// `renderer` holds now; their records go to the GPU here, once. Throws
  /// std::invalid_argument for a model index past the renderer's or a
  /// transform object_record() refuses (naming the object).
  void set_objects(const Renderer& renderer, std::span<const SceneObject> objects);

  /// One index list per object (set_objects' order; an empty list draws
  /// nothing), ids of the object's model, each drawn in ascending id order
  /// (sorted here unless it is; the stage publishes sorted lists): the lists back to back and a
  /// command per non-empty one. `models` are the hierarchies of the
  /// renderer's set_models in the same order (for the points each list stands
  /// for and the id check). O(objects + nodes); the buffers grow to the next
  /// power of two and are written alternately (never one a frame in flight
  /// reads). Throws std::invalid_argument for another number of lists than
  /// objects, other models than set_objects saw, or an id past its model.
  void upload(std::span<const Hierarchy* const> models,
              std::span<const std::span<const NodeId>> cuts);

  /// From the next upload on, the lists reach their vertices through MAP
  /// (the pool of a scene whose models are drawn from their pages,
  /// GpuNodePool; VertexMap::map_list per object); null: each id at its
  /// model's base. Not owned.
  void set_vertex_map(VertexMap* map) { map_ = map; }
  /// Maps the uploaded lists again and writes them (the map changed: pages
  /// that arrived on the GPU); nothing without a map.
  void refresh();

  /// Commands [first, first + count) whose vertices lie in one segment of
  /// a pool, in the indirect buffer's order: a draw call each. One run
  /// (segment 0) without a map; none when nothing is drawn.
  struct SegmentRun {
    std::uint32_t first = 0;
    std::uint32_t count = 0;
    std::uint32_t segment = 0;
  };
  [[nodiscard]] std::span<const SegmentRun> segment_runs() const { return segment_runs_; }

  [[nodiscard]] std::size_t object_count() const { return object_models_.size(); }
  /// Nodes in all lists.
  [[nodiscard]] std::size_t size() const { return size_; }
  /// Indirect commands (objects with a non-empty list).
  [[nodiscard]] std::size_t commands() const { return commands_; }
  /// Input points the lists stand for (each object counts its own).
  [[nodiscard]] std::uint64_t points() const { return points_; }
  /// The models the objects were set for (identities, never dereferenced).
  [[nodiscard]] std::span<const Hierarchy* const> models() const { return models_; }

  [[nodiscard]] const gl::Buffer& objects() const { return records_; }
  [[nodiscard]] const gl::Buffer& elements() const { return elements_[current_]; }
  [[nodiscard]] const gl::Buffer& indirect() const { return indirect_[current_]; }

 private:
  // The lists' elements and commands into the buffers no frame in flight reads.
  void write();
  // Through the map: each list's vertices grouped by segment, a command per
  // object and segment, into elements (grouped_) and cmds_.
  void map_lists();

  // An object's list in ids_.
  struct List {
    std::uint32_t object = 0, first = 0, count = 0;
  };
  VertexMap* map_ = nullptr;
  std::vector<List> lists_;
  std::vector<SegmentRun> segment_runs_;
  std::vector<std::uint32_t> vertices_;       // mapped lists, as ids_ (reused)
  std::vector<std::uint32_t> list_vertices_;  // one list's (reused)
  std::vector<std::uint32_t> grouped_;        // their vertices by segment (reused)
  std::vector<std::uint32_t> owner_;          // the list of each grouped_ entry (reused)
  std::vector<std::uint32_t> at_;             // counting sort: per segment (reused)
  std::vector<std::uint32_t> object_models_;  // per object: its model (the records hold the rest)
  std::vector<const Hierarchy*> models_;
  std::vector<std::uint32_t> model_base_;
  gl::Buffer records_;
  std::array<gl::Buffer, 2> elements_;
  std::array<gl::Buffer, 2> indirect_;
  std::size_t current_ = 0;
  std::size_t size_ = 0;
  std::size_t commands_ = 0;
  std::uint64_t points_ = 0;
  std::vector<NodeId> ids_;          // reused
  std::vector<std::uint32_t> cmds_;  // reused: 5 words per command
  std::vector<NodeId> sorted_;       // an unsorted list, sorted (reused)
  std::vector<NodeId> scratch_;      // radix sort ping-pong (reused)
};

}  // namespace treecut::splat
