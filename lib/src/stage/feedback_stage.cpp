// FeedbackStage on one model: the constructor (the model's cut, sorted once,
// is the first front list). The wait/process exchange of "Parallel
// TreeCut Manipulation" (Marton, Schiffner et al.), section 3, figure 2, is
// split by job beside this file: feedback_stage_thread.cpp (the stage
// thread: start, Wait, shutdown), feedback_stage_process.cpp (Process:
// Extract, Iterate, Publish), feedback_stage_exchange.cpp (the render
// thread's poll, request and exchange), feedback_stage_inputs.cpp (inputs
// for the next request), feedback_stage_scene.cpp (a stage on a scene),
// feedback_stage_errors.cpp (a strategy's failure, named). See
// feedback_stage.hpp and docs/threading.md for the ownership rules.
#include "treecut/feedback_stage.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

#include "feedback_stage_impl.hpp"

namespace treecut {
namespace {

#if !defined(NDEBUG)
constexpr bool kCheckedBuild = true;
#elif defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kCheckedBuild = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(undefined_behavior_sanitizer)
constexpr bool kCheckedBuild = true;
#else
constexpr bool kCheckedBuild = false;
#endif
#else
constexpr bool kCheckedBuild = false;
#endif

}  // namespace

bool validate_cuts_by_default() {
  return kCheckedBuild;
}

FeedbackStage::Impl::Impl(Model model, std::unique_ptr<Strategy> strategy, StageOptions options)
    : options_(options) {
  if (!model.hierarchy || model.hierarchy->empty()) {
    throw std::invalid_argument("FeedbackStage: the model has no hierarchy");
  }
  if (!strategy) throw std::invalid_argument("FeedbackStage: no strategy");
  if (options_.list_buffers < 2) throw std::invalid_argument("FeedbackStage: fewer than 2 buffers");
  if (std::string why = model.cut.validate(*model.hierarchy); !why.empty()) {
    throw std::invalid_argument("FeedbackStage: invalid initial cut: " + why);
  }
  buffers_.resize(options_.list_buffers);
  ListBuffer& first = buffers_[0];
  first.nodes.assign(model.cut.nodes().begin(), model.cut.nodes().end());
  std::sort(first.nodes.begin(), first.nodes.end());  // once; every list is ascending
  first.hierarchy = model.hierarchy;
  first.generation = 1;
  first.use = BufferUse::Front;
  front_ = 0;
  front_view_ = list_of(front_);

  strategy_name_ = std::string(strategy->name());
  pending_.specs = strategy->param_specs();
  hierarchy_ = std::move(model.hierarchy);
  paged_ = std::move(model.paged);
  cut_ = std::move(model.cut);
  strategy_ = std::move(strategy);
  running_ = strategy_.get();
  strategy_->reset(*hierarchy_);
  if (options_.launch == Launch::Thread) thread_ = std::thread([this] { run(); });
}

}  // namespace treecut
