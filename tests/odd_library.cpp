// Shared libraries that no host should have to survive loading, one per
// TREECUT_ODD variant (tests/plugin.cmake builds each): plugin_gl_test checks
// that `load_plugin` names them instead of dying or exiting with them.
//   crash:  the constructor crashes (as a bad pointer in a complete dynamic
//           section crashes the dynamic loader itself);
//   exit0:  the constructor ends the process with exit status 0;
//   exit42: ... with 42;
//   data:   the entry points are variables, not functions.
#include <csignal>
#include <cstdint>
#include <cstdlib>

#if defined(TREECUT_ODD_CRASH)
namespace {
[[gnu::constructor]] void crash_on_load() {
  std::raise(SIGSEGV);
}
}  // namespace
#elif defined(TREECUT_ODD_EXIT0)
namespace {
[[gnu::constructor]] void exit_on_load() {
  std::exit(0);
}
}  // namespace
#elif defined(TREECUT_ODD_EXIT42)
namespace {
[[gnu::constructor]] void exit_on_load() {
  std::exit(42);
}
}  // namespace
#elif defined(TREECUT_ODD_DATA)
// What a plugin author might write by mistake: right names, wrong kind.
extern "C" {
[[gnu::visibility("default")]] std::uint32_t treecut_plugin_api_version = 3;
[[gnu::visibility("default")]] std::uint32_t treecut_plugin_register = 0;
}
#else
#error "define one TREECUT_ODD_* variant"
#endif
