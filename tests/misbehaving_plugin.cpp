// A plugin whose strategies break the rules of docs/plugin-guide.md, one rule
// each, so tests can check what the host makes of it (plugin_gl_test, built by
// tests/plugin.cmake): every error names the strategy and this file.
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "treecut/plugin.hpp"
#include "treecut/strategy.hpp"

namespace {

enum class Fault { DropsNode, Duplicate, EmptyCut, ThrowsInt, IgnoresCancel };

class Misbehaving final : public treecut::Strategy {
 public:
  Misbehaving(const char* name, Fault fault) : Strategy({}), name_(name), fault_(fault) {}
  [[nodiscard]] std::string_view name() const override { return name_; }
  [[nodiscard]] Mode mode() const override {
    return fault_ == Fault::DropsNode || fault_ == Fault::Duplicate ? Mode::Rebuild : Mode::Evolve;
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
      case Fault::Duplicate:
        // Every leaf, the first one twice in place of the second: the point
        // total is right, so only TreeCut::validate (--validate, checked
        // builds) sees it.
        for (treecut::NodeId n = 0; n < h.node_count(); ++n) {
          if (h.is_leaf(n)) out.nodes->push_back(n);
        }
        (*out.nodes)[1] = (*out.nodes)[0];
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
  add("duplicate", Fault::Duplicate, "test plugin: a Rebuild cut listing a node twice");
  add("empty_cut", Fault::EmptyCut, "test plugin: an Evolve strategy that empties its cut");
  add("throws_int", Fault::ThrowsInt, "test plugin: throws an int");
  add("ignores_cancel", Fault::IgnoresCancel, "test plugin: ignores cancellation for a minute");
}
