// FeedbackStage's public face (treecut/feedback_stage.hpp): every call
// forwards to the implementation (feedback_stage_impl.hpp), so the header
// shows the API and nothing of the buffers, the exchange's state or the two
// threads' members. One pointer more per call; poll() stays allocation-free
// and lock-free.
#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"

namespace treecut {

FeedbackStage::FeedbackStage(Model model, std::unique_ptr<Strategy> strategy, StageOptions options)
    : impl_(std::make_unique<Impl>(std::move(model), std::move(strategy), options)) {}

FeedbackStage::FeedbackStage(std::shared_ptr<const StageScene> scene,
                             const StrategyFactory& factory, StageOptions options)
    : impl_(std::make_unique<Impl>(std::move(scene), factory, options)) {}

FeedbackStage::~FeedbackStage() = default;

FrameLists FeedbackStage::poll() {
  return impl_->poll();
}
void FeedbackStage::set_view(const ViewSnapshot& view) {
  impl_->set_view(view);
}
void FeedbackStage::post_visibility(std::span<const VisibilityResult> results) {
  impl_->post_visibility(results);
}
void FeedbackStage::set_strategy(std::unique_ptr<Strategy> strategy) {
  impl_->set_strategy(std::move(strategy));
}
void FeedbackStage::set_strategy(StrategyFactory factory) {
  impl_->set_strategy(std::move(factory));
}
const std::shared_ptr<const StageScene>& FeedbackStage::scene() const {
  return impl_->scene();
}
void FeedbackStage::set_param(std::string_view name, double value) {
  impl_->set_param(name, value);
}
void FeedbackStage::set_model(Model model) {
  impl_->set_model(std::move(model));
}
void FeedbackStage::set_blend_frames(unsigned frames) {
  impl_->set_blend_frames(frames);
}
unsigned FeedbackStage::blend_frames() const {
  return impl_->blend_frames();
}
const StageCounters& FeedbackStage::counters() const {
  return impl_->counters();
}
std::uint64_t FeedbackStage::frame() const {
  return impl_->frame();
}
const FrontList& FeedbackStage::front() const {
  return impl_->front();
}
const std::string& FeedbackStage::strategy_name() const {
  return impl_->strategy_name();
}
bool FeedbackStage::processing() const {
  return impl_->processing();
}
bool FeedbackStage::step() {
  return impl_->step();
}
bool FeedbackStage::can_boost() const {
  return impl_->can_boost();
}

}  // namespace treecut
