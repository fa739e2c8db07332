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
// (no allocation, no lock): registering is async-signal-safe to read.
#pragma once

#include <cstddef>
#include <string_view>

namespace treecut::detail {

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
