// StrategyRegistry: strategies by name, built-in and from plugins, so the
// program and the Controller can select one at run time.
//
// Not synchronized: register and load plugins on one thread (at start-up),
// then create() and list() may be called from any thread concurrently.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/strategy.hpp"

namespace treecut {

using StrategyFactory = std::function<std::unique_ptr<Strategy>()>;

struct StrategyInfo {
  std::string name;
  std::string description;
  std::vector<ParamSpec> params;  ///< as a freshly created instance reports them
  std::string origin;             ///< "built-in" or the plugin's path
};

class StrategyRegistry {
 public:
  /// Adds a strategy. The factory is called once here to read the parameter
  /// specs. Throws std::invalid_argument for an empty or duplicate name, or a
  /// factory whose product reports another name.
  void add(std::string name, std::string description, StrategyFactory factory);

  /// A new instance; throws InputError ("unknown strategy 'x' (known: a, b)").
  [[nodiscard]] std::unique_ptr<Strategy> create(std::string_view name) const;
  [[nodiscard]] bool contains(std::string_view name) const;
  /// Every registered strategy, sorted by name.
  [[nodiscard]] std::vector<StrategyInfo> list() const;
  [[nodiscard]] std::vector<std::string> names() const;

  /// Loads a plugin shared library and calls its registration function (see
  /// plugin.hpp). Throws InputError when the file cannot be loaded, lacks the
  /// entry points, was built for another plugin API version, or registers a
  /// duplicate name. A loaded library stays loaded until the process exits, so
  /// strategy objects it created never outlive their code.
  void load_plugin(const std::filesystem::path& path);

 private:
  /// Tries load_and_register() in a child process first (registry.cpp);
  /// throws InputError naming PATH when that fails, crashes or exits.
  void try_plugin_in_child(const std::filesystem::path& path,
                           const std::filesystem::path& open_as) const;
  /// dlopen of OPEN_AS (PATH, checked and made absolute), its entry points,
  /// its version, then registration (all or nothing); throws InputError
  /// naming PATH.
  void load_and_register(const std::filesystem::path& path, const std::filesystem::path& open_as);

  struct Entry {
    StrategyInfo info;
    StrategyFactory factory;
  };
  [[nodiscard]] const Entry* find(std::string_view name) const;

  std::vector<Entry> entries_;
  std::string origin_ = "built-in";
};

}  // namespace treecut
