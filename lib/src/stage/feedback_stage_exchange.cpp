// The render thread's side of "Parallel TreeCut Manipulation" (Marton,
// Schiffner et al.), section 3, figure 2: poll() once per frame (the
// lock-free query of the state), the Exchange of back and front list (O(1),
// indices only), request() (the inbox filled, Process stored, the stage woken
// if parked), the list buffers' uses and the detection of a starved stage
// (its boost: feedback_stage_priority.cpp). No
// lock, and no allocation once the pending vectors have grown: these functions
// stay in one file so that poll() inlines them as before the split
// (RenderThread.PollExchangeAndRequestNeverAllocate, tests/core/poll_alloc_test.cpp). See
// feedback_stage.hpp and docs/threading.md for the ownership rules this file relies on.
// Model-checked: tests/model/exchange.pml is this protocol in Promela, with the same names (states,
// buffer uses, poll/exchange/request/retire); change both.
#include <algorithm>
#include <chrono>
#include <exception>
#include <optional>
#include <utility>

#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"

namespace treecut {

FrontList FeedbackStage::Impl::list_of(std::uint32_t index) const {
  const ListBuffer& b = buffers_[index];
  return FrontList{b.nodes, b.generation, b.hierarchy.get(), b.queries, b.offsets, scene_.get()};
}

std::optional<std::uint32_t> FeedbackStage::Impl::free_buffer() const {
  for (std::uint32_t i = 0; i < buffers_.size(); ++i) {
    if (buffers_[i].use == BufferUse::Free) return i;
  }
  return std::nullopt;
}

// A list the renderer no longer draws: it was copied in the frame of its
// exchange (CutBuffer::follow), so the stage may write it again at once.
void FeedbackStage::Impl::retire(std::uint32_t index) {
  buffers_[index].use = BufferUse::Free;
}

// The Exchange: O(1), swaps which buffer is the front; no list is copied.
void FeedbackStage::Impl::exchange() {
  const std::uint32_t old = front_;
  front_ = back_;
  buffers_[front_].use = BufferUse::Front;
  if (options_.blend_frames > 0) {
    if (blending_) retire(*blending_);
    blending_ = old;
    buffers_[old].use = BufferUse::Blending;
    blend_frame_ = 0;
  } else {
    retire(old);
  }
  front_view_ = list_of(front_);
  ++counters_.exchanges;
  if (front_view_.hierarchy == switching_to_) switching_to_ = nullptr;
}

bool FeedbackStage::Impl::request() {
  const std::optional<std::uint32_t> free = free_buffer();
  if (!free) {
    ++counters_.no_free_buffer;
    return false;
  }
  back_ = *free;
  buffers_[back_].use = BufferUse::Back;
  inbox_.view = pending_.view;
  inbox_.view.frame = counters_.frames;
  pending_.view.visibility.clear();
  pending_.view_changed = false;
  if (pending_.strategy) running_ = pending_.strategy.get();
  inbox_.strategy = std::move(pending_.strategy);
  inbox_.factory = std::move(pending_.factory);
  pending_.factory = nullptr;
  inbox_.params.swap(pending_.params);
  if (pending_.model) {
    inbox_.model = std::move(pending_.model);
    pending_.model.reset();
  }
  inbox_.back = back_;
  inbox_.front = front_;
  inbox_.generation = next_generation_++;
  frames_at_request_ = counters_.frames;
  requested_at_ = std::chrono::steady_clock::now();
  starved_ = false;
  in_flight_ = true;
  ++counters_.requests;
  // A cancel stored before this point was for an earlier iteration. Cleared
  // here, not by the stage: set_strategy(), set_model() or the destructor may
  // cancel this iteration before the stage thread has even woken up.
  cancel_.store(false, std::memory_order_relaxed);
  // seq_cst, paired with await_request(): a stage that is not parked sees the
  // new state by itself, so the wake-up (a system call) is only paid after a
  // long idle period.
  state_.store(State::Process, std::memory_order_seq_cst);
  if (parked_.load(std::memory_order_seq_cst)) state_.notify_one();
  return true;
}

FrameLists FeedbackStage::Impl::poll() {
  ++counters_.frames;
  FrameLists f;
  if (blending_ && ++blend_frame_ >= options_.blend_frames) {
    retire(*blending_);
    blending_.reset();
  }
  // The lock-free query of figure 2.
  const State state = state_.load(std::memory_order_acquire);
  if (state == State::Process && in_flight_ && !starved_ && options_.starvation_bound.count() > 0 &&
      std::chrono::steady_clock::now() - requested_at_ >= options_.starvation_bound) {
    // Bounded wait: a Low/Idle stage that has not delivered within the bound
    // runs at the creator's priority until this iteration is done.
    starved_ = true;
    ++counters_.starved;
    set_boost(true);
  }
  // A fade runs to its end before the next exchange: an exchange in the
  // middle of one would snap the pixels still fading (and with an iteration
  // per frame no fade would ever get past its first step). The finished list
  // waits in the back buffer meanwhile; an error is reported at once.
  const bool hold = blending_ && in_flight_ && state == State::Wait && outbox_.ready;
  if (state == State::Wait && !hold) {
    if (in_flight_) {
      in_flight_ = false;
      set_boost(false);
      counters_.frames_last_iteration = counters_.frames - frames_at_request_;
      const auto wait = outbox_.started - requested_at_;
      counters_.wait_ns_last =
          wait.count() > 0 ? static_cast<std::uint64_t>(
                                 std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count())
                           : 0;
      counters_.wait_ns_max = std::max(counters_.wait_ns_max, counters_.wait_ns_last);
      if (outbox_.error) {
        buffers_[back_].use = BufferUse::Free;
        ++counters_.errors;
        if (outbox_.invalid_cut) ++counters_.invalid_cuts;
        try {
          std::rethrow_exception(outbox_.error);
        } catch (const std::exception& e) {
          counters_.last_error = e.what();
        }
        std::rethrow_exception(std::exchange(outbox_.error, nullptr));
      }
      ++counters_.iterations;
      counters_.iteration_ns_last = outbox_.iteration_ns;
      counters_.iteration_ns_total += outbox_.iteration_ns;
      counters_.extract_ns_last = outbox_.extract_ns;
      counters_.extract_ns_total += outbox_.extract_ns;
      counters_.publish_ns_last = outbox_.publish_ns;
      counters_.objects_last = outbox_.objects;
      counters_.last = outbox_.result;
      // Converged for the inputs it ran on: a parameter, strategy or model
      // handed over while it ran is not in its answer (issue 30: a script's
      // `param max_nodes` then `converge` returned at once, on the old budget).
      converged_ = outbox_.result.converged && !outbox_.result.cancelled &&
                   pending_.params.empty() && !pending_.strategy && !pending_.model;
      counters_.converged = converged_;
      if (outbox_.ready) {
        outbox_.ready = false;
        exchange();
        f.exchanged = true;
      }
    }
    const bool due = !converged_ || pending_.view_changed || pending_.strategy ||
                     !pending_.params.empty() || pending_.model ||
                     !pending_.view.visibility.empty();
    if (due) f.requested = request();
  }
  f.current = front_view_;
  if (blending_) {
    f.previous = list_of(*blending_);
    f.blend = static_cast<float>(blend_frame_ + 1) / static_cast<float>(options_.blend_frames + 1);
  }
  return f;
}

}  // namespace treecut
