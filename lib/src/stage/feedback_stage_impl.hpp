// Private to the FeedbackStage sources (lib/src/stage/feedback_stage*.cpp):
// what more than one of them needs beyond the class itself. Only the stage
// thread's start (feedback_stage_thread.cpp) and the render thread's boost
// (feedback_stage_exchange.cpp) change a thread's priority, with this one
// function.
#pragma once

#include "treecut/feedback_stage.hpp"

#if defined(__linux__)
#include <pthread.h>
#endif

namespace treecut::detail {

#if defined(__linux__)
// Lowers a stage thread (by its handle and tid; Linux keeps a nice value per thread, so
// PRIO_PROCESS with a thread id changes that thread only). `idle` chooses SCHED_IDLE over nice +19
// for Idle: only a process that may raise the thread again uses SCHED_IDLE, since an unprivileged
// thread can never leave it (sched(7), RLIMIT_NICE).
void apply_low_priority(pthread_t thread, int tid, int base_nice, StagePriority priority,
                        bool idle);
#endif

}  // namespace treecut::detail
