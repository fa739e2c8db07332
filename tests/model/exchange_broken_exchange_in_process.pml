/*
 * Deliberately broken: poll() handles a completed iteration, and so
 * exchanges, without first seeing the stage in Wait (an exchange allowed in
 * Process). spin must report the render thread reading the outbox or a list
 * while the stage writes it. Everything else is tests/model/exchange.pml.
 * spin-flags:
 */
#define BROKEN_POLL

inline poll(idx, found, old, thrown) {
  thrown = false;
  if
  :: in_flight -> completed(old, thrown) /* BROKEN: in any state */
  :: else -> skip
  fi;
  if
  :: state == Wait && !thrown -> due(idx, found)
  :: else -> skip
  fi
}

#include "exchange.pml"
