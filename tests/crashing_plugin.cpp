// A shared library that crashes as it is loaded, as one damaged inside (a
// bad pointer in its dynamic section, with complete headers) crashes the
// dynamic loader: its constructor writes through a null pointer. plugin_test
// checks that `load_plugin` names it instead of dying with it.
#include <csignal>

namespace {

[[gnu::constructor]] void crash_on_load() {
  std::raise(SIGSEGV);
}

}  // namespace
