#include "support/signal_guard.hpp"

#include <pthread.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csetjmp>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <mutex>

namespace treecut::detail {

namespace {

// A slot's life: free -> filling (its registrant writes it) -> ready -> free
// again, or ready -> claimed when a handler takes it (never reused: the
// process is ending).
enum SlotState : int { kFree = 0, kFilling = 1, kReady = 2, kClaimed = 3 };

struct TemporarySlot {
  std::atomic<int> state{kFree};
  pid_t owner = 0;  // a child made by fork() inherits the table, not the files
  char path[4096];
};
struct MappingSlot {
  std::atomic<int> state{kFree};
  std::uintptr_t begin = 0, end = 0;
  char shown[1024];
};

// 64 outputs under construction and 256 mapped files at once are far above
// what one treecut process holds (a scene maps one cache per distinct model;
// past the table its mappings only lose the message, not correctness).
TemporarySlot g_temporaries[64];
MappingSlot g_mappings[256];

static_assert(std::atomic<int>::is_always_lock_free);

template <class Slot, std::size_t N>
int take_slot(Slot (&slots)[N]) noexcept {
  for (std::size_t i = 0; i < N; ++i) {
    int expected = kFree;
    if (slots[i].state.compare_exchange_strong(expected, kFilling, std::memory_order_acquire))
      return static_cast<int>(i);
  }
  return -1;
}

template <class Slot, std::size_t N>
void release_slot(Slot (&slots)[N], int slot) noexcept {
  if (slot < 0 || static_cast<std::size_t>(slot) >= N) return;
  int expected = kReady;
  // Fails only when a handler claimed it: the process is ending, leave it.
  slots[slot].state.compare_exchange_strong(expected, kFree, std::memory_order_release);
}

void write_all(int fd, const char* text, std::size_t size) noexcept {
  while (size > 0) {
    const ssize_t n = ::write(fd, text, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    text += n;
    size -= static_cast<std::size_t>(n);
  }
}

// Threads between a temporary's creation and its registration, and whether
// a handler has begun to end the process (TemporaryInTheMaking).
std::atomic<int> g_making{0};
std::atomic<bool> g_ending{false};
thread_local bool t_making = false;

// Called by a handler that ends the process. Sequentially consistent on both
// sides: either the maker sees g_ending and creates nothing, or this sees
// its count and waits for the registration.
void remove_temporaries() noexcept {
  g_ending.store(true);
  // A SIGBUS on a thread that is itself making one does not wait for itself.
  while (g_making.load() > (t_making ? 1 : 0)) {
    const timespec pause{0, 100'000};
    ::nanosleep(&pause, nullptr);
  }
  const pid_t self = ::getpid();
  for (TemporarySlot& s : g_temporaries) {
    int expected = kReady;
    if (s.state.load(std::memory_order_acquire) != kReady || s.owner != self) continue;
    if (s.state.compare_exchange_strong(expected, kClaimed, std::memory_order_acquire))
      ::unlink(s.path);
  }
}

// The innermost run_guarded() of this thread: a plain pointer, so reading it
// in the handler needs no initialisation (static TLS of the executable).
struct Guard {
  sigjmp_buf* jump;
  std::uintptr_t begin, end;
};
thread_local Guard* t_guard = nullptr;

struct sigaction g_previous_bus;

// A SIGBUS that is not ours goes where it went before this handler existed.
void pass_on_bus(int sig, siginfo_t* info, void* context) noexcept {
  const struct sigaction& p = g_previous_bus;
  if ((p.sa_flags & SA_SIGINFO) != 0 && p.sa_sigaction != nullptr) {
    p.sa_sigaction(sig, info, context);
    return;
  }
  if (p.sa_handler != SIG_DFL && p.sa_handler != SIG_IGN) {
    p.sa_handler(sig);
    return;
  }
  // The default action: returning re-runs the faulting access, which now
  // ends the process as SIGBUS always did.
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(SIGBUS, &dfl, nullptr);
}

void on_bus(int sig, siginfo_t* info, void* context) noexcept {
  const auto address = reinterpret_cast<std::uintptr_t>(info->si_addr);
  if (Guard* g = t_guard; g != nullptr && address >= g->begin && address < g->end)
    siglongjmp(*g->jump, 1);
  for (MappingSlot& s : g_mappings) {
    if (s.state.load(std::memory_order_acquire) != kReady) continue;
    if (address < s.begin || address >= s.end) continue;
    int expected = kReady;
    if (!s.state.compare_exchange_strong(expected, kClaimed, std::memory_order_acquire)) continue;
    static constexpr char kPrefix[] = "treecut: error: ";
    static constexpr char kReason[] =
        ": changed while being read (truncated or rewritten by another program)\n";
    write_all(STDERR_FILENO, kPrefix, sizeof kPrefix - 1);
    write_all(STDERR_FILENO, s.shown, std::strlen(s.shown));
    write_all(STDERR_FILENO, kReason, sizeof kReason - 1);
    remove_temporaries();
    ::_exit(1);
  }
  pass_on_bus(sig, info, context);
}

// SIGINT and friends: remove the temporaries, then die of the signal.
void on_terminate(int sig) noexcept {
  remove_temporaries();
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, sig);
  ::pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
  ::raise(sig);
}

void install_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    // A child made by fork() has only the forking thread: the others'
    // creations in progress are not its to wait for.
    ::pthread_atfork(nullptr, nullptr, [] { g_making.store(0); });
    struct sigaction bus {};
    bus.sa_sigaction = on_bus;
    bus.sa_flags = SA_SIGINFO;
    sigemptyset(&bus.sa_mask);
    ::sigaction(SIGBUS, &bus, &g_previous_bus);
    for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) {
      struct sigaction now {};
      if (::sigaction(sig, nullptr, &now) != 0) continue;
      // Ignored or handled by the program: its choice stands.
      if ((now.sa_flags & SA_SIGINFO) != 0 || now.sa_handler != SIG_DFL) continue;
      struct sigaction term {};
      term.sa_handler = on_terminate;
      sigemptyset(&term.sa_mask);
      // The other termination signals wait while one removes the files.
      for (const int other : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) sigaddset(&term.sa_mask, other);
      ::sigaction(sig, &term, nullptr);
    }
  });
}

void copy_text(char* to, std::size_t capacity, std::string_view from) noexcept {
  const std::size_t n = std::min(from.size(), capacity - 1);
  std::memcpy(to, from.data(), n);
  to[n] = '\0';
}

}  // namespace

TemporaryInTheMaking::TemporaryInTheMaking() noexcept {
  install_handlers();
  sigset_t set;
  sigemptyset(&set);
  for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) sigaddset(&set, sig);
  ::pthread_sigmask(SIG_BLOCK, &set, &previous_);
  g_making.fetch_add(1);
  t_making = true;
  if (g_ending.load()) {
    // A handler on another thread is ending the process; this thread's
    // termination signals are blocked, so it waits here for the end,
    // having created nothing.
    t_making = false;
    g_making.fetch_sub(1);
    for (;;) ::pause();
  }
}

TemporaryInTheMaking::~TemporaryInTheMaking() {
  t_making = false;
  g_making.fetch_sub(1);
  ::pthread_sigmask(SIG_SETMASK, &previous_, nullptr);
}

int register_temporary(std::string_view absolute_path) noexcept {
  if (absolute_path.size() >= sizeof(TemporarySlot::path)) return -1;
  install_handlers();
  const int slot = take_slot(g_temporaries);
  if (slot < 0) return -1;
  TemporarySlot& s = g_temporaries[slot];
  s.owner = ::getpid();
  copy_text(s.path, sizeof s.path, absolute_path);
  s.state.store(kReady, std::memory_order_release);
  return slot;
}

void unregister_temporary(int slot) noexcept {
  release_slot(g_temporaries, slot);
}

int register_mapping(const void* begin, std::size_t size, std::string_view shown) noexcept {
  install_handlers();
  const int slot = take_slot(g_mappings);
  if (slot < 0) return -1;
  MappingSlot& s = g_mappings[slot];
  s.begin = reinterpret_cast<std::uintptr_t>(begin);
  s.end = s.begin + size;
  copy_text(s.shown, sizeof s.shown, shown);
  s.state.store(kReady, std::memory_order_release);
  return slot;
}

void unregister_mapping(int slot) noexcept {
  release_slot(g_mappings, slot);
}

bool run_guarded(const void* begin, std::size_t size, void (*fn)(void*), void* ctx) {
  install_handlers();
  sigjmp_buf jump;
  Guard guard{&jump, reinterpret_cast<std::uintptr_t>(begin),
              reinterpret_cast<std::uintptr_t>(begin) + size};
  Guard* const outer = t_guard;
  // savemask 1: the handler runs with SIGBUS blocked; the jump restores the mask.
  if (sigsetjmp(jump, 1) != 0) {
    t_guard = outer;
    return false;
  }
  t_guard = &guard;
  fn(ctx);
  t_guard = outer;
  return true;
}

}  // namespace treecut::detail
