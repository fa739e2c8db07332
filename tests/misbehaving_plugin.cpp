// A plugin whose strategies break the rules of docs/plugin-guide.md, one rule
// each, so tests can check what the host makes of it (plugin_test, built by
// tests/plugin.cmake): every error names the strategy and this file.
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "treecut/plugin.hpp"
#include "treecut/strategy.hpp"

namespace {

enum class Fault { DropsNode, EmptyCut, ThrowsInt, IgnoresCancel };

class Misbehaving final : public treecut::Strategy {
 public:
  Misbehaving(const char* name, Fault fault) : Strategy({}), name_(name), fault_(fault) {}
  [[nodiscard]] std::string_view name() const override { return name_; }
  [[nodiscard]] Mode mode() const override {
    return fault_ == Fault::DropsNode ? Mode::Rebuild : Mode::Evolve;
  }
  void reset(const treecut::Hierarchy&) override {}
  void iterate(const treecut::IterationInput& in, treecut::IterationOutput& out) override {
    const treecut::Hierarchy& h = in.hierarchy;
    switch (fault_) {
      case Fault::DropsNode:  // the cut one level below the root, one child missing
        for (treecut::NodeId c = h.first_child(0); c + 1 < h.first_child(0) + h.child_count(0);
             ++c) {
          out.nodes->push_back(c);
        }
        break;
      case Fault::EmptyCut:
        *out.cut = treecut::TreeCut();
        break;
      case Fault::ThrowsInt:
        throw 42;
      case Fault::IgnoresCancel:
        // Never looks at in.cancelled(); gives up after a minute.
        std::this_thread::sleep_for(std::chrono::seconds(60));
        break;
    }
    out.result.converged = true;
  }

 private:
  const char* name_;
  Fault fault_;
};

}  // namespace

TREECUT_PLUGIN(registry) {
  const auto add = [&](const char* name, Fault fault, const char* what) {
    registry.add(name, what, [name, fault] { return std::make_unique<Misbehaving>(name, fault); });
  };
  add("drops_node", Fault::DropsNode, "test plugin: a Rebuild cut missing a node");
  add("empty_cut", Fault::EmptyCut, "test plugin: an Evolve strategy that empties its cut");
  add("throws_int", Fault::ThrowsInt, "test plugin: throws an int");
  add("ignores_cancel", Fault::IgnoresCancel, "test plugin: ignores cancellation for a minute");
}
