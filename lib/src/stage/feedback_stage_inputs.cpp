// The render thread's inputs for the next request of the Feedback Stage
// ("Parallel TreeCut Manipulation", Marton, Schiffner et al., section 3): the
// view and the visibility answers, strategy switches (an instance or a
// scene's factory), parameters and a model switch, all kept pending until
// request() hands them over; a switch cancels a running iteration. See
// feedback_stage.hpp and docs/threading.md. Model-checked:
// tests/model/exchange.pml models set_strategy() and set_model() (hand-over
// and cancel); change both.
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "feedback_stage_impl.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"

namespace treecut {

void FeedbackStage::Impl::set_view(const ViewSnapshot& view) {
  ViewSnapshot& p = pending_.view;
  if (view.version != p.version) pending_.view_changed = true;
  // One assignment of the whole value (a field added later is never dropped);
  // the pending results survive it in the scratch vector, and both vectors
  // keep their capacity, so this allocates only while they grow.
  std::vector<VisibilityResult>& kept = pending_.visibility_scratch;
  kept.swap(p.visibility);
  p = view;
  kept.insert(kept.end(), p.visibility.begin(), p.visibility.end());
  kept.swap(p.visibility);
  kept.clear();
}

void FeedbackStage::Impl::post_visibility(std::span<const VisibilityResult> results) {
  // Until the new model's first list is drawn, every answer is about the old one.
  if (switching_to_ != nullptr) return;
  pending_.view.visibility.insert(pending_.view.visibility.end(), results.begin(), results.end());
}

void FeedbackStage::Impl::set_strategy(std::unique_ptr<Strategy> strategy) {
  if (!strategy) throw std::invalid_argument("FeedbackStage: no strategy");
  if (scene_ && dynamic_cast<const SceneStrategy*>(strategy.get()) == nullptr) {
    throw std::invalid_argument(
        "FeedbackStage: a per-object strategy on a scene needs a StrategyFactory");
  }
  pending_.factory = nullptr;
  strategy_name_ = std::string(strategy->name());
  pending_.specs = strategy->param_specs();
  pending_.strategy = std::move(strategy);
  pending_.params.clear();  // they were meant for the strategy being replaced
  converged_ = counters_.converged = false;
  if (state_.load(std::memory_order_relaxed) == State::Process) {
    cancel_.store(true, std::memory_order_relaxed);
  }
}

void FeedbackStage::Impl::set_strategy(StrategyFactory factory) {
  if (!factory) throw std::invalid_argument("FeedbackStage: no strategy factory");
  std::unique_ptr<Strategy> first = factory();
  if (!first) throw std::invalid_argument("FeedbackStage: the factory made no strategy");
  if (!scene_) {
    set_strategy(std::move(first));
    return;
  }
  check_scene_strategy(*first);
  strategy_name_ = std::string(first->name());
  pending_.specs = first->param_specs();
  pending_.strategy = std::move(first);
  pending_.factory = std::move(factory);
  pending_.params.clear();
  converged_ = counters_.converged = false;
  if (state_.load(std::memory_order_relaxed) == State::Process) {
    cancel_.store(true, std::memory_order_relaxed);
  }
}

void FeedbackStage::Impl::set_param(std::string_view name, double value) {
  for (const ParamSpec& spec : pending_.specs) {
    if (spec.name != name) continue;
    if (std::string why = check_param(spec, value); !why.empty()) {
      throw InputError(strategy_name_ + ": " + why);
    }
    pending_.params.emplace_back(std::string(name), value);
    converged_ = counters_.converged = false;
    return;
  }
  throw InputError(strategy_name_ + ": unknown parameter '" + std::string(name) + "'");
}

void FeedbackStage::Impl::set_model(Model model) {
  if (scene_) throw std::logic_error("FeedbackStage: set_model on a stage made on a scene");
  if (!model.hierarchy || model.hierarchy->empty()) {
    throw std::invalid_argument("FeedbackStage: the model has no hierarchy");
  }
  if (std::string why = model.cut.validate(*model.hierarchy); !why.empty()) {
    throw std::invalid_argument("FeedbackStage: invalid cut: " + why);
  }
  // Answers not yet handed over name nodes of the model being replaced.
  pending_.view.visibility.clear();
  switching_to_ = model.hierarchy.get();
  pending_.model = std::move(model);
  converged_ = counters_.converged = false;
  if (state_.load(std::memory_order_relaxed) == State::Process) {
    cancel_.store(true, std::memory_order_relaxed);
  }
}

}  // namespace treecut
