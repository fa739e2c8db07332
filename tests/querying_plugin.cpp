// A plugin with a strategy that posts GPU queries (built by
// tests/plugin.cmake): render_command_gl_test needs one with a fixed, known set
// of requests to see the query columns of stats.csv and the queries block of
// summary.json filled in by a real run (the built-in `hoq` queries too, but
// what it asks depends on its answers).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "treecut/plugin.hpp"
#include "treecut/strategy.hpp"

namespace {

// The cut of the root's children, and every iteration a query about each of
// them (QueryKind::Samples) and one about the root (QueryKind::AnySamples).
// Never converges: each iteration is a new list with new requests.
class Querying final : public treecut::Strategy {
 public:
  Querying() : Strategy({}) {}
  [[nodiscard]] std::string_view name() const override { return "querying"; }
  [[nodiscard]] Mode mode() const override { return Mode::Rebuild; }
  [[nodiscard]] bool asks_queries() const override { return true; }
  void reset(const treecut::Hierarchy&) override { tag_ = 0; }
  void iterate(const treecut::IterationInput& in, treecut::IterationOutput& out) override {
    const treecut::Hierarchy& h = in.hierarchy;
    for (treecut::NodeId c = h.first_child(0); c < h.first_child(0) + h.child_count(0); ++c) {
      out.nodes->push_back(c);
      out.queries->push_back(treecut::query_about(in, c, tag_++));
    }
    out.queries->push_back(treecut::query_about(in, 0, tag_++, treecut::QueryKind::AnySamples));
    out.result.converged = false;
  }

 private:
  std::uint32_t tag_ = 0;
};

}  // namespace

TREECUT_PLUGIN(registry) {
  registry.add("querying", "test plugin: posts a query per cut node and one about the root",
               [] { return std::make_unique<Querying>(); });
}
