/*
 * Deliberately broken: the destructor stores Exit without waiting for a
 * running iteration to return to Wait. The stage then overwrites Exit with
 * Wait, waits for a request that never comes, and join() never returns:
 * spin must report an invalid end state (a deadlock). Everything else is
 * tests/model/exchange.pml.
 * spin-flags:
 */
#define BROKEN_DESTRUCTOR

inline destructor() {
  shutting_down = true;
  atomic { cancel = true; cancel_requested = true };
  state = Exit; /* BROKEN: no while (Process) state_.wait(Process) */
  (stage_exited)
}

#include "exchange.pml"
