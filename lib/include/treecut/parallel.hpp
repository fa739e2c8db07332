// Minimal fork-join parallelism for the data-parallel passes (attributes,
// hierarchy build, generators). Static partitioning: block b of `blocks` covers
// a fixed index range, so results that are combined per block are deterministic
// for any thread count.
#pragma once

#include <algorithm>
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

namespace treecut {

/// Hardware threads, or `requested` when non-zero.
inline unsigned worker_count(unsigned requested = 0) {
  if (requested) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

/// Calls body(begin, end) on disjoint sub-ranges of [0, n) from up to
/// `threads` threads (the calling thread takes part). Ranges smaller than
/// `grain` run inline. The first exception thrown by any body is rethrown.
template <class Body>
void parallel_for(std::size_t n, Body&& body, unsigned threads = 0, std::size_t grain = 4096) {
  const unsigned workers = static_cast<unsigned>(std::min<std::size_t>(
      worker_count(threads), (n + grain - 1) / std::max<std::size_t>(grain, 1)));
  if (workers <= 1) {
    if (n) body(std::size_t{0}, n);
    return;
  }
  std::vector<std::exception_ptr> errors(workers);
  auto run = [&](unsigned w) {
    const std::size_t b = n * w / workers, e = n * (w + 1) / workers;
    try {
      body(b, e);
    } catch (...) {
      errors[w] = std::current_exception();
    }
  };
  std::vector<std::jthread> pool;
  pool.reserve(workers - 1);
  for (unsigned w = 1; w < workers; ++w) pool.emplace_back(run, w);
  run(0);
  pool.clear();  // joins
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace treecut
