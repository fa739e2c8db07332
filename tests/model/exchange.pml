/*
 * The wait/process exchange of the Feedback Stage, as implemented in
 * lib/src/stage/feedback_stage*.cpp and lib/include/treecut/feedback_stage.hpp
 * (Marton, Schiffner et al., "Parallel TreeCut Manipulation", section 3,
 * figure 2; docs/threading.md). tests/model/check.sh verifies it with spin.
 *
 * The names are the code's: the states Wait, Process, Exit (State), the
 * buffer uses Free, Back, Front, Blending (BufferUse); the render
 * thread's poll() (with completed(), its in_flight_ branch, and due(), its
 * `due` test), exchange(), request(), retire(), free_buffer(),
 * set_strategy() (set_model() hands over and cancels the same way) and the
 * destructor; the stage's run() and process() with its steps extract(),
 * iterate() and publish() (extract_ns, iteration_ns, publish_ns in the code).
 * draw() is the renderer using FrameLists between two polls. Variables carry the names of the members they stand
 * for (state_ -> state, cancel_ -> cancel, buffers_[i].use -> use[i], ...).
 *
 * What is abstracted: list contents (a list is its buffer index), counters,
 * generations, the view and the pending
 * inputs (a request may be due in any frame), blend_frames (a blending list
 * may retire in any poll; the hold of a finished list until a fade ends is
 * not modelled: it only removes interleavings), the strategy's mode (the stage's cut may be stale
 * after any iteration), whether an iteration throws, converges or is a
 * strategy that returns only when cancelled (tests' GateStrategy).
 *
 * Properties:
 *  - no invalid end state: the destructor always returns, nobody blocks;
 *  - ownership (assertions): the render thread never reads a list the stage
 *    is writing (it copies what it draws within the frame: CutBuffer::follow),
 *    the stage never writes a list the render thread reads or one it reads
 *    itself, and the inbox and outbox are never accessed by both threads at
 *    once;
 *  - a cancel the render thread asks for (set_strategy, set_model, the
 *    destructor) while an iteration is requested reaches that iteration;
 *  - ltl shutdown_completes (the destructor returns) and cancel_returns (a
 *    cancelled iteration returns to Wait), under weak fairness.
 *
 * Configurations (spin -D...): BUFFERS = StageOptions::list_buffers (>= 2,
 * default 3), BLEND = blend_frames > 0. (A manual release mode, with the GPU
 * reading lists until release(), was removed with ReleaseMode: the renderer
 * copies every list.)
 *
 * The deliberately broken variants (exchange_broken_*.pml) each replace one
 * inline below (the #ifndef BROKEN_* hooks) and include this file.
 */

#ifndef BUFFERS
#define BUFFERS 3
#endif

mtype = { Wait, Process, Exit };                  /* FeedbackStage::State */
mtype = { Free, Back, Front, Blending };  /* FeedbackStage::BufferUse */

/* The only synchronization: state_ (acquire/release) and cancel_ (no data). */
mtype state = Wait;
bool cancel = false;

/* Shared data, owned by the render thread in Wait and by the stage in Process. */
byte inbox_back;        /* Inbox::back: the list the stage writes */
byte inbox_front;       /* Inbox::front: the list the stage may read */
bool outbox_ready;      /* Outbox::ready */
bool outbox_error;      /* Outbox::error */
bool outbox_converged;  /* Outbox::result.converged && !cancelled */

/* Render thread only. */
mtype use[BUFFERS];  /* buffers_[i].use */
byte front_ = 0;
byte back_ = 0;
byte blending_ = 0;
bool has_blending = false;  /* blending_.has_value() */
bool in_flight = false;     /* in_flight_ */
bool converged_ = false;

/* Stage thread only. */
bool cut_stale = false;  /* cut_stale_ */

/* Ghost state for the properties (no counterpart in the code). */
byte render_reading[BUFFERS];  /* the renderer draws the list this frame */
bool stage_reading[BUFFERS];
bool stage_writing[BUFFERS];
bool render_inbox = false;
bool stage_inbox = false;
bool render_outbox = false;
bool stage_outbox = false;
bool cancel_requested = false;  /* the render thread asked the requested iteration to stop */
bool shutting_down = false;
bool stage_exited = false;

/* ---- ownership checks: an access starts only if the other side is not in one ---- */

inline render_read_begin(b) {
  atomic { assert(!stage_writing[b]); render_reading[b]++ }
}
inline render_read_end(b) { render_reading[b]-- }
inline stage_read_begin(b) {
  atomic { assert(!stage_writing[b]); stage_reading[b] = true }
}
inline stage_read_end(b) { stage_reading[b] = false }
inline stage_write_begin(b) {
  atomic {
    assert(render_reading[b] == 0 && !stage_reading[b]);
    stage_writing[b] = true
  }
}
inline stage_write_end(b) { stage_writing[b] = false }
inline render_inbox_begin() { atomic { assert(!stage_inbox); render_inbox = true } }
inline render_inbox_end() { render_inbox = false }
inline stage_inbox_begin() { atomic { assert(!render_inbox); stage_inbox = true } }
inline stage_inbox_end() { stage_inbox = false }
inline render_outbox_begin() { atomic { assert(!stage_outbox); render_outbox = true } }
inline render_outbox_end() { render_outbox = false }
inline stage_outbox_begin() { atomic { assert(!render_outbox); stage_outbox = true } }
inline stage_outbox_end() { stage_outbox = false }

/* ---- render thread ---- */

/* FeedbackStage::retire: a list the renderer no longer draws (it was copied). */
inline retire(b) {
  use[b] = Free
}

/* FeedbackStage::free_buffer: the first Free buffer. */
#ifndef BROKEN_FREE_BUFFER
inline free_buffer(idx, found) {
  d_step {
    idx = 0;
    found = false;
    do
    :: idx < BUFFERS && use[idx] == Free -> found = true; break
    :: idx < BUFFERS && use[idx] != Free -> idx++
    :: idx >= BUFFERS -> break
    od
  }
}
#endif

/* FeedbackStage::exchange: O(1), the back list becomes the front list. */
inline exchange(old) {
  old = front_;
  front_ = back_;
  use[front_] = Front;
#ifdef BLEND
  if
  :: has_blending -> retire(blending_)
  :: else -> skip
  fi;
  blending_ = old;
  has_blending = true;
  use[old] = Blending
#else
  retire(old)
#endif
}

/* FeedbackStage::request: hand the inputs over, Wait -> Process. */
inline request(idx, found) {
  free_buffer(idx, found);
  if
  :: !found -> skip /* counters_.no_free_buffer */
  :: found ->
     back_ = idx;
     use[back_] = Back;
     render_inbox_begin();
     inbox_back = back_;
     inbox_front = front_;
     render_inbox_end();
     in_flight = true;
     /* cancel_.store(false): a cancel asked for before this request was for
        an earlier iteration. */
     atomic { cancel = false; cancel_requested = false };
     state = Process /* store(release) + notify_one */
  fi
}

/* poll(), in Wait: the requested iteration completed; read the outbox and
   exchange. THROWN: the strategy's exception is rethrown to the caller. */
inline completed(old, thrown) {
  in_flight = false;
  render_outbox_begin();
  if
  :: outbox_error -> /* the back list is dropped */
     outbox_error = false;
     render_outbox_end();
     use[back_] = Free;
     thrown = true
  :: else ->
     converged_ = outbox_converged;
     if
     :: outbox_ready ->
        outbox_ready = false;
        render_outbox_end();
        exchange(old)
     :: else -> render_outbox_end()
     fi
  fi
}

/* poll(), in Wait: request when due (not converged, or the view changed or
   an input is pending, which may be any frame). */
inline due(idx, found) {
  if
  :: !converged_ -> request(idx, found)
  :: converged_ ->
     if
     :: request(idx, found)
     :: skip
     fi
  fi
}

/* FeedbackStage::poll, once per frame. */
#ifndef BROKEN_POLL
inline poll(idx, found, old, thrown) {
#ifdef BLEND
  if
  :: has_blending -> /* blend_frames polls later (any poll, here) */
     if
     :: retire(blending_); has_blending = false
     :: skip
     fi
  :: else -> skip
  fi;
#endif
  thrown = false;
  if
  :: state == Wait -> /* the lock-free query of figure 2 (load acquire) */
     if
     :: in_flight -> completed(old, thrown)
     :: else -> skip
     fi;
     if
     :: !thrown -> due(idx, found)
     :: else -> skip
     fi
  :: else -> skip
  fi
}
#endif

/* The renderer draws FrameLists::current (and ::previous while blending). */
inline draw() {
  render_read_begin(front_);
#ifdef BLEND
  if
  :: has_blending -> render_read_begin(blending_)
  :: else -> skip
  fi;
#endif
  render_read_end(front_);
#ifdef BLEND
  if
  :: has_blending -> render_read_end(blending_)
  :: else -> skip
  fi
#endif
}

/* FeedbackStage::set_strategy and set_model: the input waits in pending_ for
   the next request; a running iteration is asked to stop early. */
inline set_strategy() {
  converged_ = false;
  if
  :: state == Process -> atomic { cancel = true; cancel_requested = true }
  :: else -> skip
  fi
}

/* FeedbackStage::~FeedbackStage. */
#ifndef BROKEN_DESTRUCTOR
inline destructor() {
  shutting_down = true;
  atomic { cancel = true; cancel_requested = true };
  (state != Process); /* while (Process) state_.wait(Process) */
  state = Exit;       /* only this thread leaves Wait: no request slips in */
  (stage_exited)      /* thread_.join() */
}
#endif

active proctype RenderThread() {
  byte idx;
  bool found;
  byte old;
  bool thrown;
  byte i;
  d_step {
    use[0] = Front; /* the initial cut, generation 1 */
    i = 1;
    do
    :: i < BUFFERS -> use[i] = Free; i++
    :: else -> break
    od
  };
  do
  :: poll(idx, found, old, thrown); draw()
  :: set_strategy()
  :: break /* the owner destroys the stage */
  od;
  destructor()
}

/* ---- Feedback Stage thread ---- */

/* process(), step Extract: take the inputs the render thread handed over. */
#ifndef BROKEN_EXTRACT
inline extract(b, f) {
  stage_inbox_begin();
  b = inbox_back;
  f = inbox_front;
  stage_inbox_end();
  assert(b != f);
  if
  :: cut_stale -> /* Evolve after Rebuild: TreeCut::from_nodes(front list) */
     stage_read_begin(f);
     stage_read_end(f);
     cut_stale = false
  :: skip /* a Rebuild strategy, or the cut is current */
  fi
}
#endif

/* process(), step Iterate: Strategy::iterate writes the back list and polls
   cancel_; a gate strategy returns only when cancelled. */
inline iterate(b, gate) {
  stage_write_begin(b);
  if
  :: gate = true
  :: gate = false
  fi;
  do
  :: cancel -> break
  :: !gate -> break
  od;
  assert(!cancel_requested || cancel)
}

/* process(), step Publish: the cut into the back list, then the outbox. */
inline publish(b) {
  if
  :: cut_stale = true  /* Rebuild: the back list is not the stage's cut */
  :: cut_stale = false /* Evolve: the cut is copied into the back list */
  fi;
  stage_write_end(b);
  stage_outbox_begin();
  if
  :: outbox_ready = true; outbox_error = false
  :: outbox_ready = false; outbox_error = true /* the strategy threw */
  fi;
  if
  :: outbox_converged = true
  :: outbox_converged = false
  fi;
  stage_outbox_end()
}

/* FeedbackStage::process, in Process: inbox, outbox and the back list are the
   stage's; the front list is read-only. */
inline process(b, f, gate) {
  extract(b, f);
  iterate(b, gate);
  publish(b);
  state = Wait /* store(release) + notify_all */
}

/* FeedbackStage::run. */
active proctype FeedbackThread() {
  byte b;
  byte f;
  bool gate;
  do
  :: state != Wait -> /* state_.wait(Wait) returned */
     if
     :: state == Exit -> break
     :: state == Process -> process(b, f, gate)
     :: else -> skip
     fi
  od;
  stage_exited = true
}

ltl shutdown_completes { [] (shutting_down -> <> stage_exited) }
ltl cancel_returns { [] ((state == Process && cancel) -> <> (state != Process)) }
