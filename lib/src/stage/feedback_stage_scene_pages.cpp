// A scene whose models are drawn from their pages (issue 45: "every strategy
// and the scene mode work on a paged model"): on the stage thread, around a
// scene's iteration, what a single paged model's Process does
// (feedback_stage_process.cpp, follow_pages) for each paged model: the
// pages read join it before the iteration, the pages its objects want most
// (the largest on screen under each object's view) are asked for after it,
// and the pages no object's list reaches into are given back.
// docs/architecture.md, "Scenes through the stage".
#include <algorithm>
#include <chrono>
#include <unordered_set>
#include <utility>
#include <vector>

#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/paged_hierarchy.hpp"

namespace treecut {

using detail::fold_object_view;
using detail::object_list;

namespace {

// Pages asked for per model and iteration at most (as a single model's rank()).
constexpr std::size_t kAskedPerModel = 64;

// What two models' pages do, added up (memory short when any one is).
void add_stats(PagingStats& total, const PagingStats& s) {
  total.pages += s.pages;
  total.resident_pages += s.resident_pages;
  total.resident_nodes += s.resident_nodes;
  total.resident_bytes += s.resident_bytes;
  total.requested += s.requested;
  total.in_flight += s.in_flight;
  total.loaded += s.loaded;
  total.evicted += s.evicted;
  total.failed += s.failed;
  total.bytes_read += s.bytes_read;
  total.memory_short = total.memory_short || s.memory_short;
}

}  // namespace

// Stage thread, before a scene's iteration.
void FeedbackStage::Impl::publish_scene_pages() {
  const std::size_t models = scene_->paged.size();
  model_revealed_.resize(models);
  model_concealed_.resize(models);
  for (std::size_t m = 0; m < models; ++m)
    if (PagedHierarchy* paged = scene_->paged_model(m)) paged->publish(&model_revealed_[m]);
  scene_wanted_.clear();
}

// Stage thread, after a scene's iteration into the back list: per paged
// model, asks for the pages its objects wanted, the largest on screen
// first, and gives back what no object's list (the back one, or the front
// one the render thread draws meanwhile) reaches into.
void FeedbackStage::Impl::follow_scene_pages(Outbox& out) {
  const std::size_t n = scene_->objects.size();
  const std::size_t models = scene_->paged.size();
  const ListBuffer& back = buffers_[inbox_.back];
  const ListBuffer& front = buffers_[inbox_.front];

  // Each wanted node's projected radius under its object's view (the
  // object's size factor as its iteration had it), by model.
  std::vector<std::vector<std::pair<float, NodeId>>> ranked(models);
  std::size_t viewed = n;  // the object whose view object_view_ holds
  for (const ObjectNode& w : scene_wanted_) {
    if (w.object >= n) continue;
    const SceneObject& o = scene_->objects[w.object];
    const Hierarchy& h = *scene_->models[o.model];
    if (scene_->paged_model(o.model) == nullptr || w.node >= h.node_count() || !h.is_hidden(w.node))
      continue;
    if (viewed != w.object) {
      fold_object_view(object_view_, view_, o);
      object_view_.derived.pixel_scale *=
          object_size_factor_[object_view_.derived.perspective ? 1 : 0][w.object];
      viewed = w.object;
    }
    const float px = object_view_.projected_radius_px(h.center(w.node), h.radius(w.node));
    ranked[o.model].emplace_back(-px, w.node);
  }

  PagingStats total;
  std::vector<NodeId> asked, listed;
  std::unordered_set<NodeId> reached;
  for (std::size_t m = 0; m < models; ++m) {
    PagedHierarchy* paged = scene_->paged_model(m);
    if (paged == nullptr) continue;
    const Hierarchy& h = *scene_->models[m];
    // The most wanted first, each node once (two objects may want it).
    std::vector<std::pair<float, NodeId>>& r = ranked[m];
    std::sort(r.begin(), r.end());
    asked.clear();
    for (const auto& [score, node] : r) {
      if (asked.size() == kAskedPerModel) break;
      if (std::find(asked.begin(), asked.end(), node) == asked.end()) asked.push_back(node);
    }
    paged->request(asked);

    // A page no list reaches into: no object's list holds a node below the
    // node its group hangs from. The objects' lists are cuts (or empty: not
    // drawn), so a list that holds such a node holds neither that node nor
    // an ancestor; the one test for every object is whether the node is a
    // strict ancestor of a listed node. Those ancestors, gathered once.
    listed.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (scene_->objects[i].model != m) continue;
      for (const ListBuffer* list : {&back, &front}) {
        const std::span<const NodeId> l = object_list(list->nodes, list->offsets, n, i);
        listed.insert(listed.end(), l.begin(), l.end());
      }
    }
    std::sort(listed.begin(), listed.end());
    listed.erase(std::unique(listed.begin(), listed.end()), listed.end());
    reached.clear();
    const std::span<const NodeId> parent = h.arrays().parent;
    for (const NodeId node : listed)
      for (NodeId up = parent[node]; up != kNoNode && reached.insert(up).second;) up = parent[up];
    const std::vector<PagedHierarchy::ListHolds> lists{
        [&reached](NodeId node) { return !reached.contains(node); }};
    // This iteration took what the pages did; what the next one takes
    // starts with what is given back now.
    model_revealed_[m].clear();
    model_concealed_[m].clear();
    paged->evict(lists, &model_concealed_[m]);
    const PagingStats s = paged->stats();
    add_stats(total, s);
  }
  // Not converged while pages it wants are on their way.
  if (!scene_wanted_.empty() || total.in_flight > 0) out.result.converged = false;
  detail::report_pages(total, scene_wanted_.size(), out.result.counters);
}

}  // namespace treecut
