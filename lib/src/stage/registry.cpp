#include "treecut/registry.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <stdexcept>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/plugin.hpp"

namespace treecut {

const StrategyRegistry::Entry* StrategyRegistry::find(std::string_view name) const {
  for (const Entry& e : entries_) {
    if (e.info.name == name) return &e;
  }
  return nullptr;
}

void StrategyRegistry::add(std::string name, std::string description, StrategyFactory factory) {
  if (name.empty() || !factory) throw std::invalid_argument("strategy: empty name or factory");
  if (find(name) != nullptr) {
    throw std::invalid_argument("strategy '" + name + "' is already registered");
  }
  const std::unique_ptr<Strategy> probe = factory();
  if (!probe || probe->name() != name) {
    throw std::invalid_argument("strategy '" + name + "': the factory makes another strategy");
  }
  entries_.push_back(
      {StrategyInfo{std::move(name), std::move(description), probe->param_specs(), origin_},
       std::move(factory)});
}

bool StrategyRegistry::contains(std::string_view name) const {
  return find(name) != nullptr;
}

std::unique_ptr<Strategy> StrategyRegistry::create(std::string_view name) const {
  if (const Entry* e = find(name)) {
    std::unique_ptr<Strategy> s = e->factory();
    if (!s)
      throw std::runtime_error("strategy '" + e->info.name + "' (" + e->info.origin +
                               "): the factory returned no strategy");
    s->set_origin(e->info.origin);
    return s;
  }
  std::string known;
  for (const std::string& n : names()) known += (known.empty() ? "" : ", ") + n;
  throw InputError("unknown strategy '" + std::string(name) + "' (known: " + known + ")");
}

std::vector<StrategyInfo> StrategyRegistry::list() const {
  std::vector<StrategyInfo> out;
  out.reserve(entries_.size());
  for (const Entry& e : entries_) out.push_back(e.info);
  std::sort(out.begin(), out.end(),
            [](const StrategyInfo& a, const StrategyInfo& b) { return a.name < b.name; });
  return out;
}

std::vector<std::string> StrategyRegistry::names() const {
  std::vector<std::string> out;
  for (const Entry& e : entries_) out.push_back(e.info.name);
  std::sort(out.begin(), out.end());
  return out;
}

void StrategyRegistry::load_plugin(const std::filesystem::path& path) {
  const std::string where = path.string();
  // dlopen() of a FIFO blocks in open() and of a device reads from it: a file
  // that exists must be a regular file. A bare name that names no file here
  // is searched on the library path (dlopen's rule); one that does is this
  // file, so "--plugin libx.so" in its folder loads it (dlopen alone would
  // search elsewhere and report "No such file"). A missing path is left to
  // dlopen's own message.
  std::string open_as = where;
  if (file_kind(path) != FileKind::Missing) {
    require_regular_file(path);
    if (where.find('/') == std::string::npos) open_as = "./" + where;
  }
  // RTLD_LOCAL: two plugins may define the same internal symbols. The handle is
  // never closed (see the header), so it is deliberately not kept.
  void* handle = dlopen(open_as.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = dlerror();
    throw InputError(where + ": cannot load plugin: " + (why != nullptr ? why : "unknown error"));
  }
  using VersionFn = std::uint32_t (*)();
  using RegisterFn = void (*)(StrategyRegistry&);
  auto* version = reinterpret_cast<VersionFn>(dlsym(handle, kPluginVersionSymbol));
  auto* entry = reinterpret_cast<RegisterFn>(dlsym(handle, kPluginRegisterSymbol));
  if (version == nullptr || entry == nullptr) {
    dlclose(handle);  // nothing from it was used yet
    throw InputError(where + ": not a treecut plugin (no " + kPluginVersionSymbol + "/" +
                     kPluginRegisterSymbol + ")");
  }
  if (const std::uint32_t v = version(); v != kPluginApiVersion) {
    dlclose(handle);
    throw InputError(where + ": plugin API version " + std::to_string(v) + ", this treecut has " +
                     std::to_string(kPluginApiVersion));
  }
  const std::size_t before = entries_.size();
  origin_ = where;
  try {
    entry(*this);
  } catch (const std::exception& e) {
    entries_.resize(before);  // all or nothing
    origin_ = "built-in";
    throw InputError(where + ": plugin registration failed: " + e.what());
  } catch (...) {
    entries_.resize(before);
    origin_ = "built-in";
    throw InputError(where + ": plugin registration failed");
  }
  origin_ = "built-in";
}

}  // namespace treecut
