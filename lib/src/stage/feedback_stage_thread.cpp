// The stage thread of "Parallel TreeCut Manipulation" (Marton, Schiffner et
// al.), section 3, figure 2: its start (its priority lowered, as
// feedback_stage_priority.cpp does it), its loop
// (await_request: spin, poll, park until Process or Exit; then process()),
// step() for Launch::Manual, and the destructor's shutdown (cancel, wait for
// a running iteration, Exit, join). See feedback_stage.hpp and
// docs/threading.md for the ownership rules this file relies on.
// Model-checked: tests/model/exchange.pml is this protocol in Promela, with the
// same names (states, run/process, the destructor); change both.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/file_io.hpp"

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace treecut {

FeedbackStage::Impl::~Impl() {
  cancel_.store(true, std::memory_order_relaxed);
  if (!thread_.joinable()) return;
  // Shutdown while Process runs: let the (cancelled) iteration return to Wait,
  // then tell the thread to exit. Only this thread moves Wait -> anything, so
  // no request can slip in between. A starved low-priority stage would reach
  // the cancel check late: raise it first. The iteration reads the stage's
  // lists, cut and hierarchy, so there is no safe way to leave without it:
  // past cancel_timeout the wait is reported, then goes on.
  using Clock = std::chrono::steady_clock;
  if (state_.load(std::memory_order_acquire) == State::Process) {
    set_boost(true);
    const Clock::time_point since = Clock::now();
    while (state_.load(std::memory_order_acquire) == State::Process &&
           Clock::now() - since < options_.cancel_timeout) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (state_.load(std::memory_order_acquire) == State::Process) {
      char seconds[32];
      std::snprintf(seconds, sizeof seconds, "%.1f",
                    std::chrono::duration<double>(Clock::now() - since).count());
      const std::string what = describe_strategy(running_->name(), running_->origin()) +
                               " ignored cancellation for " + seconds + " s";
      if (options_.on_slow_cancel) {
        options_.on_slow_cancel(what);
      } else {
        std::fprintf(stderr, "warning: %s; waiting for it to return\n", one_line(what).c_str());
      }
    }
    while (state_.load(std::memory_order_acquire) == State::Process) {
      state_.wait(State::Process, std::memory_order_acquire);
    }
  }
  state_.store(State::Exit, std::memory_order_release);
  state_.notify_all();
  thread_.join();
}

void FeedbackStage::Impl::run() {
#if defined(__linux__)
  if (options_.priority != StagePriority::Normal) {
    const int tid = static_cast<int>(syscall(SYS_gettid));
    errno = 0;
    const int nice = getpriority(PRIO_PROCESS, static_cast<id_t>(tid));
    // May this thread be raised back once lowered? Try it on a small step:
    // one nice level down, then back up (needs CAP_SYS_NICE or RLIMIT_NICE).
    bool raisable = false;
    if (errno == 0 && nice < 19 &&
        setpriority(PRIO_PROCESS, static_cast<id_t>(tid), nice + 1) == 0) {
      raisable = setpriority(PRIO_PROCESS, static_cast<id_t>(tid), nice) == 0;
    }
    stage_tid_ = tid;
    base_nice_ = errno == 0 ? nice : 0;
    detail::apply_low_priority(pthread_self(), tid, base_nice_, options_.priority, raisable);
    boostable_.store(raisable, std::memory_order_release);
  }
#endif
  for (;;) {
    if (await_request() == State::Exit) return;
    process();
  }
}

// Stage thread, state == Wait: returns once the render thread has moved the
// state to Process or Exit. Spin, then poll, then park (StageOptions).
FeedbackStage::Impl::State FeedbackStage::Impl::await_request() {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point idle_since = Clock::now();
  for (;;) {
    const State s = state_.load(std::memory_order_acquire);
    if (s != State::Wait) return s;
    const auto idle = Clock::now() - idle_since;
    if (idle < options_.idle_spin) {
      std::this_thread::yield();
    } else if (idle < options_.idle_park_after) {
      std::this_thread::sleep_for(options_.idle_poll_interval);
    } else {
      // Park. Dekker-style with request(): it stores Process, then reads
      // parked_; we store parked_, then read the state (in wait()). Both
      // sequentially consistent, so either it sees parked_ and notifies, or
      // wait() sees Process and returns: no lost wake-up.
      parked_.store(true, std::memory_order_seq_cst);
      state_.wait(State::Wait, std::memory_order_seq_cst);
      parked_.store(false, std::memory_order_relaxed);
    }
  }
}

bool FeedbackStage::Impl::step() {
  if (options_.launch != Launch::Manual) return false;
  if (state_.load(std::memory_order_acquire) != State::Process) return false;
  process();
  return true;
}

}  // namespace treecut
