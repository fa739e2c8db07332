// The engine's one parallel loop (treecut/parallel.hpp): the WorkerPool.
#include "treecut/parallel.hpp"

#include <pthread.h>
#include <time.h>

namespace treecut {

WorkerPool::WorkerPool(unsigned threads) {
  const unsigned n = std::max(threads, 1u);
  workers_.reserve(n - 1);
  for (unsigned i = 1; i < n; ++i) {
    workers_.emplace_back([this] {
      std::uint32_t seen = 0;
      for (;;) {
        Job job;
        {
          std::unique_lock lock(mutex_);
          wake_.wait(lock, [&] { return stop_ || job_.generation != seen; });
          if (stop_) return;
          job = job_;
          seen = job.generation;
        }
        take_chunks(job);
      }
    });
  }
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

std::uint64_t WorkerPool::worker_cpu_ns() const {
  std::uint64_t total = 0;
  for (const std::thread& t : workers_) {
    clockid_t clock{};
    timespec ts{};
    // const_cast: native_handle() is not const, reading the id changes nothing.
    if (pthread_getcpuclockid(const_cast<std::thread&>(t).native_handle(), &clock) != 0 ||
        clock_gettime(clock, &ts) != 0) {
      continue;
    }
    total += static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000'000u +
             static_cast<std::uint64_t>(ts.tv_nsec);
  }
  return total;
}

void WorkerPool::take_chunks(const Job& job) {
  const std::uint64_t tag = std::uint64_t{job.generation} << 32;
  for (;;) {
    std::uint64_t v = next_.load(std::memory_order_relaxed);
    std::uint32_t c = 0;
    do {
      if ((v & ~std::uint64_t{0xffffffffu}) != tag) return;  // a newer job
      c = static_cast<std::uint32_t>(v);
      if (c >= job.chunks) return;
    } while (!next_.compare_exchange_weak(v, v + 1, std::memory_order_relaxed));
    try {
      job.fn(job.ctx, c);
    } catch (...) {
      std::lock_guard lock(mutex_);
      if (!error_) error_ = std::current_exception();
    }
    // The last chunk wakes the caller; release: its results are visible.
    if (completed_.fetch_add(1, std::memory_order_acq_rel) + 1 == job.chunks) {
      std::lock_guard lock(mutex_);
      done_.notify_all();
    }
  }
}

void WorkerPool::dispatch(std::size_t chunks, ChunkFn fn, void* ctx) {
  Job job;
  {
    std::lock_guard lock(mutex_);
    job.fn = fn;
    job.ctx = ctx;
    job.chunks = static_cast<std::uint32_t>(chunks);
    job.generation = job_.generation + 1;
    completed_.store(0, std::memory_order_relaxed);
    next_.store(std::uint64_t{job.generation} << 32, std::memory_order_relaxed);
    error_ = nullptr;
    job_ = job;
  }
  wake_.notify_all();
  take_chunks(job);
  std::exception_ptr error;
  {
    std::unique_lock lock(mutex_);
    done_.wait(lock, [&] { return completed_.load(std::memory_order_acquire) == job.chunks; });
    error = error_;
    error_ = nullptr;
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace treecut
