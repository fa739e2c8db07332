// The plugin ABI: an out-of-tree shared library adds strategies to a
// StrategyRegistry at run time (`treecut strategies --plugin PATH`).
//
// A plugin defines its entry point with the macro below:
//
//   TREECUT_PLUGIN(registry) {
//     registry.add("mine", "what it does", [] { return std::make_unique<Mine>(); });
//   }
//
// The host first calls treecut_plugin_api_version() and refuses the library
// unless it equals the host's kPluginApiVersion, then calls
// treecut_plugin_register(registry). C++ types cross the boundary, so a plugin
// must be built with the same compiler family and standard library as the host
// and against the same treecut headers (find_package(treecut CONFIG) checks
// the version). See docs/plugin-guide.md.
#pragma once

#include <cstdint>

#include "treecut/registry.hpp"

namespace treecut {

/// Bumped whenever strategy.hpp, view_snapshot.hpp, registry.hpp or the
/// layout of Hierarchy/TreeCut change incompatibly.
inline constexpr std::uint32_t kPluginApiVersion = 9;

inline constexpr const char* kPluginVersionSymbol = "treecut_plugin_api_version";
inline constexpr const char* kPluginRegisterSymbol = "treecut_plugin_register";

}  // namespace treecut

#define TREECUT_PLUGIN_EXPORT extern "C" __attribute__((visibility("default")))

/// Defines the two entry points; the body that follows registers strategies
/// into `registry_var` (a treecut::StrategyRegistry&).
#define TREECUT_PLUGIN(registry_var)                                 \
  TREECUT_PLUGIN_EXPORT std::uint32_t treecut_plugin_api_version() { \
    return ::treecut::kPluginApiVersion;                             \
  }                                                                  \
  TREECUT_PLUGIN_EXPORT void treecut_plugin_register(::treecut::StrategyRegistry& registry_var)
