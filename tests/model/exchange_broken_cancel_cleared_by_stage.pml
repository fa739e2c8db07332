/*
 * Deliberately broken, and how lib/src/feedback_stage.cpp (now
 * lib/src/stage/feedback_stage_process.cpp) was until the
 * model found it: process() began with cancel_.store(false). A cancel that
 * set_strategy(), set_model() or the destructor stores between request() and
 * the stage waking up is lost: the iteration runs to its end, and one that
 * returns only when cancelled keeps the destructor waiting for ever. spin
 * must report the lost cancel (assertion) or the hang (invalid end state).
 * Everything else is tests/model/exchange.pml.
 * spin-flags:
 */
#define BROKEN_EXTRACT

inline extract(b, f) {
  cancel = false; /* BROKEN: the stage clears a cancel meant for this iteration */
  stage_inbox_begin();
  b = inbox_back;
  f = inbox_front;
  stage_inbox_end();
  assert(b != f);
  if
  :: cut_stale ->
     stage_read_begin(f);
     stage_read_end(f);
     cut_stale = false
  :: skip
  fi
}

#include "exchange.pml"
