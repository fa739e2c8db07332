// The engine's one parallel loop: a WorkerPool of persistent threads that
// run chunks of an index range, the calling thread included. The per-frame
// passes of the culling layer keep a pool; the build passes (attributes,
// hierarchy, HLOD blocks, generators) call parallel_for(), which runs one for
// the call. Results written per index, or per chunk indexed by chunk, do not
// depend on the thread count or the schedule.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace treecut {

/// Hardware threads, or `requested` when non-zero.
inline unsigned worker_count(unsigned requested = 0) {
  if (requested) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

/// A fixed set of worker threads: the one parallel loop of the engine. The
/// per-frame passes of the many-objects culler and the budget strategy keep
/// one (Peng & Cao's "object-level parallelism" on CUDA threads, here on
/// cores); parallel_for() below makes one for a call. run() splits [0, n) into chunks of `grain`
/// indices that the workers and the calling thread take in turn; it returns when all are done.
/// Results written per index (or per chunk, indexed by chunk) do not depend on the thread count or
/// the schedule. One run() at a time (one thread drives it); the first exception of a body is
/// rethrown.
class WorkerPool {
 public:
  /// `threads` >= 1 participants, the calling thread included
  /// (threads - 1 workers are started).
  explicit WorkerPool(unsigned threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  [[nodiscard]] unsigned threads() const { return static_cast<unsigned>(workers_.size()) + 1; }
  /// CPU time the worker threads (not the caller) have used so far,
  /// nanoseconds: read from their thread CPU clocks by the caller, so a
  /// phase's CPU is the caller's thread CPU plus the difference of this
  /// (what a phase costs on a machine where the wall clock counts waiting
  /// for a core).
  [[nodiscard]] std::uint64_t worker_cpu_ns() const;

  /// body(begin, end, chunk) for every chunk [begin, end) of [0, n).
  template <class Body>
  void run(std::size_t n, std::size_t grain, Body&& body) {
    if (n == 0) return;
    grain = std::max<std::size_t>(grain, 1);
    const std::size_t chunks = (n + grain - 1) / grain;
    if (chunks == 1 || workers_.empty()) {
      for (std::size_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain), c);
      return;
    }
    using Fn = std::remove_reference_t<Body>;
    struct Ctx {
      Fn* body;
      std::size_t n, grain;
    } ctx{&body, n, grain};
    dispatch(
        chunks,
        [](void* p, std::size_t c) {
          auto* x = static_cast<Ctx*>(p);
          (*x->body)(c * x->grain, std::min(x->n, (c + 1) * x->grain), c);
        },
        &ctx);
  }
  /// Chunks for n indices at this grain (to size per-chunk results).
  [[nodiscard]] static std::size_t chunk_count(std::size_t n, std::size_t grain) {
    grain = std::max<std::size_t>(grain, 1);
    return (n + grain - 1) / grain;
  }

 private:
  using ChunkFn = void (*)(void*, std::size_t);
  struct Job {
    ChunkFn fn = nullptr;
    void* ctx = nullptr;
    std::uint32_t chunks = 0;
    std::uint32_t generation = 0;
  };
  void dispatch(std::size_t chunks, ChunkFn fn, void* ctx);
  // Claims and runs chunks of `job` until none is left or a newer job began.
  void take_chunks(const Job& job);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  bool stop_ = false;  // guarded by mutex_
  Job job_;            // the current job, guarded (workers copy it)
  // generation << 32 | next chunk: a worker that wakes late cannot claim a
  // chunk of a newer job with an older job's function.
  std::atomic<std::uint64_t> next_{0};
  // Chunks of the current job finished; the caller returns when all are,
  // without waiting for workers that never woke (a loaded machine).
  std::atomic<std::uint32_t> completed_{0};
  std::exception_ptr error_;  // guarded
};

/// body(begin, end, chunk) over the chunks of `grain` indices of [0, n): on
/// `pool`, or on the calling thread in chunk order when there is none.
template <class Body>
void for_chunks(WorkerPool* pool, std::size_t n, std::size_t grain, Body&& body) {
  if (pool != nullptr) {
    pool->run(n, grain, body);
    return;
  }
  grain = std::max<std::size_t>(grain, 1);
  const std::size_t chunks = WorkerPool::chunk_count(n, grain);
  for (std::size_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain), c);
}

/// Calls body(begin, end) on disjoint sub-ranges of [0, n) from up to
/// `threads` threads (0: worker_count()), the calling thread taking part, on
/// a WorkerPool made for the call: one range per thread, so a body may set
/// up per-range scratch cheaply. Ranges smaller than `grain` run inline. The
/// first exception thrown by any body is rethrown.
template <class Body>
void parallel_for(std::size_t n, Body&& body, unsigned threads = 0, std::size_t grain = 4096) {
  const unsigned workers = static_cast<unsigned>(std::min<std::size_t>(
      worker_count(threads), (n + grain - 1) / std::max<std::size_t>(grain, 1)));
  if (workers <= 1) {
    if (n) body(std::size_t{0}, n);
    return;
  }
  WorkerPool pool(workers);
  pool.run(n, (n + workers - 1) / workers,
           [&body](std::size_t b, std::size_t e, std::size_t) { body(b, e); });
}

}  // namespace treecut
