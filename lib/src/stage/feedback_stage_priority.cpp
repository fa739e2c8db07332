// Thread scheduling of the Feedback Stage: the stage only prepares the next
// cut, so its thread gives way to the render thread and the GL driver's
// threads (StagePriority: nice +10 or SCHED_IDLE, Linux only, best effort),
// and the render thread raises it back while a request starves or the stage
// shuts down (StageOptions::starvation_bound). docs/threading.md, "Thread
// priority".
#include <algorithm>

#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#endif

namespace treecut {

#if defined(__linux__)
namespace detail {

// Declared, and explained, in feedback_stage_impl.hpp.
void apply_low_priority(pthread_t thread, int tid, int base_nice, StagePriority priority,
                        bool idle) {
  if (priority == StagePriority::Low) {
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(tid), std::min(base_nice + 10, 19));
  } else if (priority == StagePriority::Idle) {
    if (idle) {
      const sched_param param{};
      (void)pthread_setschedparam(thread, SCHED_IDLE, &param);
    } else {
      (void)setpriority(PRIO_PROCESS, static_cast<id_t>(tid), 19);
    }
  }
}

}  // namespace detail
#endif

// Render thread: raises the stage thread to the priority it started with
// (starved request, shutdown), or lowers it again.
void FeedbackStage::Impl::set_boost(bool on) {
#if defined(__linux__)
  if (on == boosted_ || !boostable_.load(std::memory_order_acquire)) return;
  boosted_ = on;
  if (on) {
    ++counters_.boosts;
    const sched_param param{};
    (void)pthread_setschedparam(thread_.native_handle(), SCHED_OTHER, &param);
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(stage_tid_), base_nice_);
  } else {
    detail::apply_low_priority(thread_.native_handle(), stage_tid_, base_nice_, options_.priority,
                               true);
  }
#else
  (void)on;
#endif
}

}  // namespace treecut
