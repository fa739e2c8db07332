/*
 * Deliberately broken: free_buffer() hands out Retired lists as well as Free
 * ones, so with ReleaseMode::Manual the stage writes a list the GPU may still
 * read (before release(generation)). spin must report the write. Everything
 * else is tests/model/exchange.pml.
 * spin-flags: -DMANUAL
 */
#define BROKEN_FREE_BUFFER
#ifndef BUFFERS
#define BUFFERS 3 /* exchange.pml's default, needed before its text */
#endif

inline free_buffer(idx, found) {
  d_step {
    idx = 0;
    found = false;
    do
    :: idx < BUFFERS && (use[idx] == Free || use[idx] == Retired) -> /* BROKEN */
       found = true;
       break
    :: idx < BUFFERS && use[idx] != Free && use[idx] != Retired -> idx++
    :: idx >= BUFFERS -> break
    od
  }
}

#include "exchange.pml"
