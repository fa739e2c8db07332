// What a signal must not leave behind: the process-wide registry of this
// process's temporary files and of the files it has mapped, and the handlers
// that act on it (private to treecut::core; AtomicFile and MappedFile are the
// only users).
//
// - SIGINT, SIGTERM, SIGHUP, SIGQUIT: the registered temporaries are removed,
//   then the signal ends the process as it would have (its default action,
//   so the shell still sees "killed by SIGTERM"). Installed only for a signal
//   whose disposition is the default: a program that ignores or handles one
//   itself keeps its choice (and unwinds, which removes them too).
// - SIGBUS at an address inside a registered mapping (the file shrank under
//   it: truncated, or rewritten in place by another program): inside
//   run_guarded() on the faulting thread, control returns there and the read
//   fails; anywhere else the temporaries are removed and the process ends
//   with exit code 1 and one line, "treecut: error: NAME: changed while being
//   read". Any other SIGBUS goes to the handler that was there before (the
//   default action, or a sanitizer's).
//
// Everything the handlers touch is a fixed table of slots with atomic states
// (no allocation, no lock): registering is async-signal-safe to read. The
// one wait in a handler is for another thread's temporary between its
// creation and its registration (a file open and a path made absolute).
#pragma once

#include <signal.h>

#include <cstddef>
#include <string_view>

namespace treecut::detail {

/// Held while a temporary is created and registered, so that no termination
/// signal leaves it behind: the signals wait on this thread, and a handler
/// running on another thread meanwhile (a process-directed signal goes to
/// any thread that does not block it) waits until the creation is over
/// before it removes the registered temporaries. Once a handler has begun,
/// a thread that starts a creation stops here for good: the process is
/// ending, and a file made now would be left behind. Installs the handlers,
/// so even the process's first temporary is covered.
class TemporaryInTheMaking {
 public:
  TemporaryInTheMaking() noexcept;
  ~TemporaryInTheMaking();
  TemporaryInTheMaking(const TemporaryInTheMaking&) = delete;
  TemporaryInTheMaking& operator=(const TemporaryInTheMaking&) = delete;

 private:
  sigset_t previous_{};
};

/// Registers an absolute temporary path; returns its slot, or -1 when the
/// table is full or the path too long (it is then only removed by unwinding).
int register_temporary(std::string_view absolute_path) noexcept;
/// The temporary was committed or removed; SLOT may be -1.
void unregister_temporary(int slot) noexcept;

/// Registers [BEGIN, BEGIN + SIZE) as a read-only mapping of the file named
/// SHOWN in messages (already quoted); returns its slot, or -1.
int register_mapping(const void* begin, std::size_t size, std::string_view shown) noexcept;
void unregister_mapping(int slot) noexcept;

/// Calls FN(CTX). Returns false, instead of ending the process, when a SIGBUS
/// hits [BEGIN, BEGIN + SIZE) on this thread meanwhile: FN's frames are left
/// by siglongjmp, so FN must hold no object with a non-trivial destructor
/// while it reads the range (hashing and checksumming loops).
bool run_guarded(const void* begin, std::size_t size, void (*fn)(void*), void* ctx);

}  // namespace treecut::detail
