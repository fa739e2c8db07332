// A scene's cut on the GPU (scene_draw.hpp): object records, the element
// list of every object's cut and its indirect commands.
#include "treecut/splat/scene_draw.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

#include "treecut/scene.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {

ObjectRecord object_record(const glm::mat4& world) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(world[c][r])) {
        throw std::invalid_argument("the transform is not finite");
      }
    }
  }
  if (world[0][3] != 0.0f || world[1][3] != 0.0f || world[2][3] != 0.0f || world[3][3] != 1.0f) {
    throw std::invalid_argument("the transform is not affine (its last row is not 0 0 0 1)");
  }
  ObjectRecord rec;
  // glm is column-major: world[column][row].
  rec.row0 = {world[0][0], world[1][0], world[2][0], world[3][0]};
  rec.row1 = {world[0][1], world[1][1], world[2][1], world[3][1]};
  rec.row2 = {world[0][2], world[1][2], world[2][2], world[3][2]};
  const glm::dmat3 l(world);
  const double det = glm::determinant(l);
  const double len[3] = {glm::length(l[0]), glm::length(l[1]), glm::length(l[2])};
  const double longest = std::max({len[0], len[1], len[2]});
  // The scene parser's own test (scene.hpp): a scene file never gets here
  // with a transform that fails it.
  if (!invertible_transform(l)) throw std::invalid_argument("the transform is not invertible");
  // A similarity (orthogonal columns of one length: rotations, mirrors,
  // uniform scales) keeps the angles of normal cones and maps a sphere to a
  // sphere: sigma is the columns' length and the widening exactly 1, so a
  // rotation or the identity culls and sizes splats as the model itself does.
  constexpr double kTolerance = 1e-6;
  bool similar = true;
  for (int i = 0; i < 3; ++i) {
    similar = similar && std::abs(len[i] - longest) <= kTolerance * longest;
    for (int j = i + 1; j < 3; ++j) {
      similar = similar && std::abs(glm::dot(l[i], l[j])) <= kTolerance * len[i] * len[j];
    }
  }
  const float sign = det > 0.0 ? 1.0f : -1.0f;
  if (similar) {
    rec.extra = {static_cast<float>(longest), 1.0f, sign, 0.0f};
    return rec;
  }
  // Otherwise bounds, rounded up: a disc of radius r becomes an ellipse
  // within radius sigma_1 r; the sine of the angle between two normals grows
  // by at most sigma_1 sigma_2 / sigma_3^2 (|Au x Av| = |det A| |A^-T (u x
  // v)| for the normal map A = L^-T).
  const std::array<double, 3> s = singular_values(world);
  constexpr double kUp = 1.0 + 1e-5;
  rec.extra = {static_cast<float>(s[0] * kUp),
               static_cast<float>(s[0] * s[1] / (s[2] * s[2]) * kUp), sign, 0.0f};
  return rec;
}

void SceneCutBuffer::set_objects(const Renderer& renderer, std::span<const SceneObject> objects) {
  if (objects.size() >= kMaxSceneDrawObjects) {
    throw std::invalid_argument("SceneCutBuffer: " + std::to_string(objects.size()) +
                                " objects, at most " + std::to_string(kMaxSceneDrawObjects - 1));
  }
  std::vector<ObjectRecord> records;
  records.reserve(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (objects[i].model >= renderer.model_count()) {
      throw std::invalid_argument("object " + std::to_string(i) + ": model " +
                                  std::to_string(objects[i].model) + " of " +
                                  std::to_string(renderer.model_count()));
    }
    try {
      records.push_back(object_record(objects[i].world));
      // The index the ObjectId mode writes (exact in a float below 2^24).
      records.back().extra.w = static_cast<float>(i);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("object " + std::to_string(i) + ": " + e.what());
    }
  }
  object_models_.resize(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) object_models_[i] = objects[i].model;
  models_.clear();
  model_base_.clear();
  for (std::size_t m = 0; m < renderer.model_count(); ++m) {
    models_.push_back(renderer.model_identity(m));
    model_base_.push_back(renderer.model_base(m));
  }
  // One record at least: an empty scene still binds a buffer.
  if (records.empty()) records.emplace_back();
  records_ = gl::Buffer::create(records.size() * sizeof(ObjectRecord), records.data(), 0);
  size_ = commands_ = 0;
  points_ = 0;
  lists_.clear();
  segment_runs_.clear();
}

void SceneCutBuffer::upload(std::span<const Hierarchy* const> models,
                            std::span<const std::span<const NodeId>> cuts) {
  if (cuts.size() != object_models_.size()) {
    throw std::invalid_argument("SceneCutBuffer: " + std::to_string(cuts.size()) + " lists for " +
                                std::to_string(object_models_.size()) + " objects");
  }
  if (!std::equal(models.begin(), models.end(), models_.begin(), models_.end())) {
    throw std::invalid_argument("SceneCutBuffer: other models than set_objects saw");
  }
  ids_.clear();
  lists_.clear();
  cmds_.clear();
  std::uint64_t points = 0;
  for (std::size_t i = 0; i < cuts.size(); ++i) {
    const std::span<const NodeId> cut = cuts[i];
    if (cut.empty()) continue;
    const Hierarchy& h = *models[object_models_[i]];
    const auto counts = h.arrays().point_count;
    const std::size_t first = ids_.size();
    for (const NodeId n : cut) {
      if (n >= h.node_count()) {
        throw std::invalid_argument("SceneCutBuffer: object " + std::to_string(i) + " names node " +
                                    std::to_string(n) + " of a model of " +
                                    std::to_string(h.node_count()));
      }
      points += counts[n];
    }
    // In node-id order, as CutBuffer draws a model's cut: spatially coherent
    // submission (docs/rendering.md), and the same image as a plain draw.
    if (std::is_sorted(cut.begin(), cut.end())) {
      ids_.insert(ids_.end(), cut.begin(), cut.end());
    } else {
      sorted_.assign(cut.begin(), cut.end());
      sort_node_ids(sorted_, static_cast<NodeId>(h.node_count()), scratch_);
      ids_.insert(ids_.end(), sorted_.begin(), sorted_.end());
    }
    const auto object = static_cast<std::uint32_t>(i);
    if (map_ != nullptr) {
      lists_.push_back(
          {object, static_cast<std::uint32_t>(first), static_cast<std::uint32_t>(cut.size())});
    } else {
      // DrawElementsIndirectCommand: count, instanceCount, firstIndex,
      // baseVertex, baseInstance (the object: its record).
      cmds_.insert(cmds_.end(),
                   {static_cast<std::uint32_t>(cut.size()), 1u, static_cast<std::uint32_t>(first),
                    model_base_[object_models_[i]], object});
    }
  }
  size_ = ids_.size();
  points_ = points;
  write();
}

void SceneCutBuffer::refresh() {
  if (map_ != nullptr) write();
}

// Without a map, upload() made the commands; with one, they are made here.
void SceneCutBuffer::write() {
  segment_runs_.clear();
  std::span<const std::uint32_t> elements = ids_;
  if (map_ != nullptr) {
    cmds_.clear();
    map_lists();
    elements = grouped_;
  } else if (!cmds_.empty()) {
    segment_runs_.push_back({0, static_cast<std::uint32_t>(cmds_.size() / 5), 0});
  }
  // Write the buffers the last draws did not read (CutBuffer::write).
  const std::size_t next = elements_[current_] ? 1 - current_ : current_;
  auto write_to = [](gl::Buffer& target, std::span<const std::byte> bytes) {
    if (!target || target.size() < bytes.size()) {
      const std::size_t capacity = std::bit_ceil(std::max<std::size_t>(bytes.size(), 4096));
      target = gl::Buffer::create(capacity, nullptr, GL_DYNAMIC_STORAGE_BIT);
    }
    if (!bytes.empty()) target.sub_data(0, bytes);
  };
  write_to(elements_[next], std::as_bytes(elements));
  write_to(indirect_[next], std::as_bytes(std::span<const std::uint32_t>(cmds_)));
  current_ = next;
  commands_ = cmds_.size() / 5;
}

void SceneCutBuffer::map_lists() {
  // Every list through the map at once (the pages any of them need are
  // wanted together), then a counting sort of the vertices by segment that
  // keeps each list's order (ascending ids: the coherent submission order)
  // and the lists' order; the null vertex (a node drawn by its stand-in) is
  // left out. Each segment's vertices as that segment numbers them.
  map_->begin_lists();
  vertices_.resize(ids_.size());
  std::uint32_t most = 0;
  for (const List& l : lists_) {
    most = std::max(most, map_->map_list(object_models_[l.object],
                                         std::span<const NodeId>(ids_).subspan(l.first, l.count),
                                         list_vertices_));
    std::copy(list_vertices_.begin(), list_vertices_.end(), vertices_.begin() + l.first);
  }
  const std::uint32_t shift = map_->segment_shift();
  const std::uint32_t place = (std::uint32_t{1} << shift) - 1;
  const std::size_t segments = (std::size_t{most} >> shift) + 1;
  at_.assign(segments + 1, 0);
  for (const std::uint32_t v : vertices_)
    if (v != 0) ++at_[(v >> shift) + 1];
  for (std::size_t g = 0; g < segments; ++g) at_[g + 1] += at_[g];
  const std::uint32_t total = at_[segments];
  grouped_.resize(total);
  owner_.resize(total);
  std::vector<std::uint32_t> next(at_.begin(), at_.end() - 1);
  for (std::uint32_t k = 0; k < lists_.size(); ++k) {
    const List& l = lists_[k];
    for (std::uint32_t i = l.first; i < l.first + l.count; ++i) {
      const std::uint32_t v = vertices_[i];
      if (v == 0) continue;
      const std::uint32_t j = next[v >> shift]++;
      grouped_[j] = v & place;
      owner_[j] = k;
    }
  }
  // A command for each run of one list within a segment.
  for (std::uint32_t g = 0; g < segments; ++g) {
    const auto first_command = static_cast<std::uint32_t>(cmds_.size() / 5);
    for (std::uint32_t j = at_[g]; j < at_[g + 1];) {
      std::uint32_t e = j;
      while (e < at_[g + 1] && owner_[e] == owner_[j]) ++e;
      cmds_.insert(cmds_.end(), {e - j, 1u, j, 0u, lists_[owner_[j]].object});
      j = e;
    }
    const auto commands = static_cast<std::uint32_t>(cmds_.size() / 5) - first_command;
    if (commands > 0) segment_runs_.push_back({first_command, commands, g});
  }
}

void Renderer::check_scene(const SceneCutBuffer& scene) const {
  const auto models = scene.models();
  if (!std::equal(models.begin(), models.end(), model_ids_.begin(), model_ids_.end())) {
    throw std::logic_error(
        "Renderer: the scene's objects were set for other models than the vertex buffer's "
        "(set_models, then SceneCutBuffer::set_objects)");
  }
  if (scene.commands() > 0 && !scene.elements()) {
    throw std::logic_error("Renderer: the scene's cut was never uploaded");
  }
}

void Renderer::bind_objects(const gl::Buffer& records) {
  gl::VertexArrayVertexBuffer(vao_.id(), kObjectBinding, records.id(), 0, sizeof(ObjectRecord));
}

}  // namespace treecut::splat
