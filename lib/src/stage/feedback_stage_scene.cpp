// A FeedbackStage on a scene: the StageScene of a loaded Scene, the
// construction (every object at its model's root, one list with object
// offsets), the size factors of stretched objects, and the strategies a scene
// runs: one SceneStrategy for all objects, or one instance of a per-object
// strategy per object, refused past kMaxPerObjectNodes. The scene's Process
// step is in feedback_stage_process.cpp; docs/architecture.md, "Scenes
// through the stage".
#include <array>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "feedback_stage_impl.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/scene.hpp"

namespace treecut {

std::uint64_t StageScene::object_nodes() const {
  std::uint64_t n = 0;
  for (const SceneObject& o : objects) {
    if (o.model < models.size() && models[o.model]) n += models[o.model]->node_count();
  }
  return n;
}

std::shared_ptr<const StageScene> stage_scene(const Scene& scene) {
  auto s = std::make_shared<StageScene>();
  s->models.reserve(scene.models.size());
  for (const SceneModel& m : scene.models) s->models.push_back(m.hierarchy);
  s->objects.reserve(scene.objects.size());
  s->objects = scene.objects;
  return s;
}

FeedbackStage::Impl::Impl(std::shared_ptr<const StageScene> scene, const StrategyFactory& factory,
                          StageOptions options)
    : options_(options), scene_(std::move(scene)) {
  if (!scene_ || scene_->objects.empty()) {
    throw std::invalid_argument("FeedbackStage: the scene has no objects");
  }
  if (!factory) throw std::invalid_argument("FeedbackStage: no strategy factory");
  if (options_.list_buffers < 2) throw std::invalid_argument("FeedbackStage: fewer than 2 buffers");
  for (const auto& m : scene_->models) {
    if (!m || m->empty()) throw std::invalid_argument("FeedbackStage: a model has no hierarchy");
  }
  const std::size_t n = scene_->objects.size();
  if (n >= std::numeric_limits<std::uint32_t>::max()) {
    throw std::invalid_argument("FeedbackStage: too many objects");
  }
  object_size_factor_[0].reserve(n);
  object_size_factor_[1].reserve(n);
  for (const SceneObject& o : scene_->objects) {
    if (o.model >= scene_->models.size()) {
      throw std::invalid_argument("FeedbackStage: an object's model index is out of range");
    }
    // A strategy sizes a node by its model-space radius over its model-space
    // distance. Under a stretch that ratio is no bound of the world's: the
    // radius grows by up to sigma_max, the distance shrinks by down to
    // sigma_min. The pixel scale takes their ratio (perspective) or sigma_max
    // (orthographic), so the projected radius stays an upper bound; a
    // similarity's ratio is exactly 1 (the identity changes nothing).
    const std::array<double, 3> sv = singular_values(o.world);
    const double hi = sv[0], lo = sv[2];
    object_size_factor_[0].push_back(static_cast<float>(hi));
    object_size_factor_[1].push_back(lo > 0.0 ? static_cast<float>(hi / lo) : 1.0f);
  }
  std::unique_ptr<Strategy> first = factory();
  if (!first) throw std::invalid_argument("FeedbackStage: the factory made no strategy");
  check_scene_strategy(*first);

  buffers_.resize(options_.list_buffers);
  ListBuffer& list = buffers_[0];
  list.nodes.reserve(n);
  list.offsets.reserve(n + 1);
  list.offsets.push_back(0);
  for (std::size_t i = 0; i < n; ++i) {
    list.nodes.push_back(scene_->models[scene_->objects[i].model]->root());
    list.offsets.push_back(static_cast<std::uint32_t>(i + 1));
  }
  list.generation = 1;
  list.use = BufferUse::Front;
  front_ = 0;
  front_view_ = list_of(front_);

  strategy_name_ = std::string(first->name());
  pending_.specs = first->param_specs();
  make_object_strategies(std::move(first), factory);
  if (!scene_strategy_ && object_strategies_[0]->mode() == Strategy::Mode::Evolve) {
    object_cuts_.reserve(n);
    for (std::size_t i = 0; i < n; ++i) object_cuts_.push_back(TreeCut::root_cut(scene_->hierarchy(i)));
  } else {
    cut_stale_ = true;
  }
  running_ = object_strategies_[0].get();
  if (options_.launch == Launch::Thread) thread_ = std::thread([this] { run(); });
}

// Render thread (constructor, set_strategy): per-object instances are state
// for every node of every object; refused past the limit, before any is made.
void FeedbackStage::Impl::check_scene_strategy(const Strategy& probe) const {
  if (std::string why = per_object_limit_problem(*scene_, probe); !why.empty()) {
    throw InputError(why);
  }
}

std::string scene_strategy_problem(const Strategy& probe) {
  if (!probe.asks_queries()) return {};
  return describe_strategy(probe.name(), probe.origin()) +
         " asks for GPU occlusion queries, which are answered for single models only "
         "(docs/architecture.md, \"Scenes through the stage\"); use a strategy without "
         "queries for a scene";
}

std::string per_object_limit_problem(const StageScene& scene, const Strategy& probe) {
  if (std::string why = scene_strategy_problem(probe); !why.empty()) return why;
  if (dynamic_cast<const SceneStrategy*>(&probe) != nullptr) return {};
  const std::uint64_t nodes = scene.object_nodes();
  if (nodes <= kMaxPerObjectNodes) return {};
  return ("a scene of " + std::to_string(scene.objects.size()) + " objects and " +
          std::to_string(nodes) +
          " nodes in all: " + describe_strategy(probe.name(), probe.origin()) +
          " runs once per object, at most " + std::to_string(kMaxPerObjectNodes) +
          " nodes in all; use a scene-level strategy (SceneStrategy, e.g. 'budget') "
          "or models of fewer points");
}

// The instances a scene runs: `first` and, for a per-object strategy, one
// more from `factory` per further object, each reset for its model.
void FeedbackStage::Impl::make_object_strategies(std::unique_ptr<Strategy> first,
                                                 const StrategyFactory& factory) {
  // Made aside and swapped in whole: a factory or reset that throws leaves
  // the instances of the strategy before (the iteration fails, the next
  // one runs them). The first instance outlives such a failure: the render
  // thread names it if the destructor waits for an iteration (running_).
  std::vector<std::unique_ptr<Strategy>> made;
  SceneStrategy* scene_level = dynamic_cast<SceneStrategy*>(first.get());
  made.push_back(std::move(first));
  try {
    if (scene_level != nullptr) {
      scene_level->reset_scene(*scene_);
    } else {
      const std::size_t n = scene_->objects.size();
      made.reserve(n);
      for (std::size_t i = 1; i < n; ++i) {
        std::unique_ptr<Strategy> s = factory ? factory() : nullptr;
        if (!s) {
          throw std::runtime_error("the strategy factory made no instance for object " +
                                   std::to_string(i));
        }
        made.push_back(std::move(s));
      }
      for (std::size_t i = 0; i < n; ++i) made[i]->reset(scene_->hierarchy(i));
    }
  } catch (...) {
    failed_first_ = std::move(made.front());
    throw;
  }
  object_strategies_.swap(made);
  scene_strategy_ = scene_level;
}

}  // namespace treecut
