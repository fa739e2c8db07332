// Paged drawing's hierarchy (treecut/paged_hierarchy.hpp, issue 45): a cache
// drawn from the pages that are wanted, read by an I/O thread, within a
// memory budget. What a whole load gives once every page is resident; the
// cut a strategy reaches standing still; the budget kept while the camera
// moves; a bad page named and the rest drawn.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "strategy_fixtures.hpp"
#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/reserved_array.hpp"
#include "treecut/strategies/builtin.hpp"
#include "treecut/strategies/event_queue.hpp"
#include "treecut/strategies/hoq.hpp"

using namespace treecut;
namespace fs = std::filesystem;

namespace {

constexpr int kWaitMs = 20000;

// A cache of several pages: a terrain of 100,000 points (about 150,000 nodes,
// pages of at most 8,192).
fs::path terrain_cache(const std::string& name) {
  const fs::path dir = test::scratch_dir(name);
  save_cache(*test::small_hierarchy(tools::ModelKind::Terrain, 100000), {1, 2, 3}, dir / "t.tch");
  return dir / "t.tch";
}

using test::reachable;

// A camera above point (X, Y) of the terrain (in [-1, 1]^2, heights within
// +-0.4), looking down and ahead: it sees a patch of a few tenths.
ViewSnapshot patch_view(float x, float y) {
  return ViewSnapshot::look_at({x, y - 0.25f, 0.7f}, {x, y + 0.05f, 0.0f}, {640, 480}, 0.8f, 0.01f,
                               10.0f);
}

// One iteration of S on CUT as the stage runs it, with what the pages did
// since the last one. Returns the hidden nodes it wants.
std::vector<NodeId> step(Strategy& s, const Hierarchy& h, TreeCut& cut, const ViewSnapshot& view,
                         std::span<const NodeId> revealed, std::span<const NodeId> concealed,
                         bool memory_short = false) {
  std::vector<NodeId> nodes, wanted;
  std::vector<QueryRequest> queries;
  IterationInput in{h, view, 0, nullptr, s.params_version(), revealed, concealed, memory_short};
  IterationOutput out{&cut, &nodes, &queries, &wanted, {}};
  s.iterate(in, out);
  if (s.mode() == Strategy::Mode::Rebuild) cut = TreeCut::from_nodes(h, nodes);
  return wanted;
}

std::vector<NodeId> sorted(const TreeCut& cut) {
  std::vector<NodeId> v(cut.nodes().begin(), cut.nodes().end());
  std::sort(v.begin(), v.end());
  return v;
}

// Iterations of S under VIEW on a paged hierarchy, asking after each for
// what the cut wants, until an iteration changes nothing and nothing
// wanted is left to read. Returns the cut.
TreeCut settle(Strategy& s, PagedHierarchy& paged, const ViewSnapshot& view) {
  const Hierarchy& h = paged.hierarchy();
  s.reset(h);
  TreeCut cut = TreeCut::root_cut(h);
  std::vector<NodeId> revealed;
  for (int i = 0; i < 400; ++i) {
    const std::vector<NodeId> before = sorted(cut);
    const std::vector<NodeId> wanted = paged.rank(step(s, h, cut, view, revealed, {}), view);
    EXPECT_EQ(cut.validate(h), "") << "iteration " << i;
    paged.request(wanted);
    EXPECT_TRUE(paged.wait_idle(kWaitMs));
    revealed.clear();
    paged.publish(&revealed);
    if (wanted.empty() && revealed.empty() && before == sorted(cut)) return cut;
  }
  ADD_FAILURE() << s.name() << " did not settle";
  return cut;
}

// The same iterations on the model held whole, until one changes nothing.
TreeCut settle(Strategy& s, const Hierarchy& h, const ViewSnapshot& view) {
  s.reset(h);
  TreeCut cut = TreeCut::root_cut(h);
  for (int i = 0; i < 400; ++i) {
    const std::vector<NodeId> before = sorted(cut);
    step(s, h, cut, view, {}, {});
    if (before == sorted(cut)) return cut;
  }
  ADD_FAILURE() << s.name() << " did not settle";
  return cut;
}

}  // namespace

TEST(PagedHierarchy, OpensWithItsFirstPageAndHidesTheRest) {
  const fs::path cache = terrain_cache("paged_open");
  const auto paged = PagedHierarchy::open(cache);
  const Hierarchy& h = paged->hierarchy();
  const Hierarchy& whole = *test::small_hierarchy(tools::ModelKind::Terrain, 100000);
  EXPECT_EQ(h.node_count(), whole.node_count());
  EXPECT_EQ(h.leaf_count(), whole.leaf_count());
  const PagingStats s = paged->stats();
  EXPECT_GT(s.pages, 2u);
  EXPECT_EQ(s.resident_pages, 1u);
  EXPECT_LT(s.resident_nodes, h.node_count());
  // The first page's nodes are a tree whose hidden leaves hold their
  // subtrees' points: a cut of them covers every point.
  const std::vector<NodeId> shown = reachable(h);
  EXPECT_EQ(shown.size(), s.resident_nodes);
  std::size_t hidden = 0;
  for (const NodeId n : shown) hidden += paged->hidden(n);
  EXPECT_GT(hidden, 0u);
  const TreeCut leaves = TreeCut::leaf_cut(h);
  EXPECT_EQ(leaves.validate(h), "");
}

TEST(PagedHierarchy, AllPagesResidentIsTheWholeLoadIdForId) {
  const fs::path cache = terrain_cache("paged_whole");
  std::string why;
  const std::optional<Hierarchy> whole = load_cache(cache, std::nullopt, &why);
  ASSERT_TRUE(whole) << why;
  const auto paged = PagedHierarchy::open(cache);
  test::load_every_page(*paged);
  const PagingStats s = paged->stats();
  EXPECT_EQ(s.resident_pages, s.pages);
  EXPECT_EQ(s.resident_nodes, whole->node_count());
  EXPECT_EQ(s.resident_bytes, whole->node_count() * paged->bytes_per_node());
  const HierarchyArrays &a = whole->arrays(), &b = paged->hierarchy().arrays();
  for (NodeId n = 0; n < whole->node_count(); ++n)
    ASSERT_EQ(test::node_difference(a, b, n), "") << n;
}

// Standing still, the cut a strategy reaches on the paged model, its pages
// read as its cut asks for them, is the cut it reaches on the model held
// whole.
TEST(PagedHierarchy, StandingStillTheCutReachesTheCutOfTheWholeModel) {
  const fs::path cache = terrain_cache("paged_still");
  std::string why;
  const std::optional<Hierarchy> whole = load_cache(cache, std::nullopt, &why);
  ASSERT_TRUE(whole) << why;
  const StrategyRegistry registry = strategies::builtin_registry();
  const ViewSnapshot view = patch_view(0.4f, 0.3f);
  for (const char* name : {"recursive", "topdown", "optimization", "bucket", "event_queue"}) {
    SCOPED_TRACE(name);
    const auto paged = PagedHierarchy::open(cache);
    const std::vector<NodeId> expect = sorted(settle(*registry.create(name), *whole, view));
    const std::vector<NodeId> got = sorted(settle(*registry.create(name), *paged, view));
    EXPECT_GT(expect.size(), 1000u);
    EXPECT_EQ(expect, got);
    // (bucket's buckets are the light's: the lit half of the model, not
    // the view's part of it.)
    if (std::string(name) != "bucket") {
      EXPECT_LT(paged->stats().resident_pages, paged->stats().pages * 3 / 4)
          << "the view wants a part of the model";
    }
  }
}

// hoq on the paged model, its blocks made over the resident nodes and its
// pages read as its blocks ask (no query answered: every block is drawn as
// if visible): the same block decisions as on the model held whole, so the
// same nodes in the view; a block out of the view is drawn as far as it is
// resident (it asks for nothing).
TEST(PagedHierarchy, HoqReachesTheWholeModelsBlocksInTheView) {
  const fs::path cache = terrain_cache("paged_hoq");
  std::string why;
  const std::optional<Hierarchy> whole = load_cache(cache, std::nullopt, &why);
  ASSERT_TRUE(whole) << why;
  const ViewSnapshot view = patch_view(0.4f, 0.3f);
  const auto in_view = [&](const TreeCut& cut) {
    std::vector<NodeId> v;
    for (const NodeId n : cut.nodes()) {
      const glm::vec4 s = whole->arrays().center_radius[n];
      if (!view.outside_frustum(glm::vec3(s), s.w)) v.push_back(n);
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  const auto make = [] {
    auto s = strategies::builtin_registry().create("hoq");
    s->set_param("block_size", 200);
    return s;
  };
  const auto paged = PagedHierarchy::open(cache);
  const std::unique_ptr<Strategy> on_whole = make(), on_paged = make();
  const TreeCut expect = settle(*on_whole, *whole, view);
  const TreeCut got = settle(*on_paged, *paged, view);
  const auto& a = dynamic_cast<const strategies::HoqStrategy&>(*on_whole);
  const auto& b = dynamic_cast<const strategies::HoqStrategy&>(*on_paged);
  EXPECT_EQ(std::vector<NodeId>(a.block_cut().begin(), a.block_cut().end()),
            std::vector<NodeId>(b.block_cut().begin(), b.block_cut().end()));
  EXPECT_GT(in_view(expect).size(), 1000u);
  EXPECT_EQ(in_view(expect), in_view(got));
  // (Not a part of this small model: a block waiting for its pages asks for
  // every hidden node of its representation, in the view or not, and the
  // root block's reaches the first page's every child group here.)
}

// Flying over the terrain with a budget of a quarter of the model, each
// strategy on a model of its own: what is resident stays within it, pages
// no cut holds are given back (a strategy lets go of what the camera
// left), and every cut holds only resident nodes. (Memory short, optimization and hoq let go of the
// detail they keep outside the frustum: IterationInput::memory_short.)
TEST(PagedHierarchy, AMovingCameraStaysWithinTheBudget) {
  const fs::path cache = terrain_cache("paged_budget");
  const Hierarchy& whole = *test::small_hierarchy(tools::ModelKind::Terrain, 100000);
  PagingOptions options;
  const std::uint64_t first_page = PagedHierarchy::open(cache)->stats().resident_bytes;
  const std::uint64_t per_node = PagedHierarchy::open(cache)->bytes_per_node();
  options.memory_bytes = first_page + whole.node_count() * per_node / 4;
  for (const char* name :
       {"recursive", "topdown", "optimization", "bucket", "event_queue", "hoq"}) {
    SCOPED_TRACE(name);
    const auto paged = PagedHierarchy::open(cache, options);
    const Hierarchy& h = paged->hierarchy();
    const std::unique_ptr<Strategy> s = strategies::builtin_registry().create(name);
    s->reset(h);
    TreeCut cut = TreeCut::root_cut(h);
    std::vector<NodeId> revealed, concealed;
    std::uint64_t most = 0;
    int short_count = 0;
    for (int k = 0; k <= 60; ++k) {
      // Along one diagonal, then along the other.
      const float t = -0.7f + 1.4f * float(k % 31) / 30.0f;
      ViewSnapshot view = patch_view(k < 31 ? t : -t, t);
      view.version = static_cast<std::uint64_t>(k) + 1;
      for (int i = 0; i < 4; ++i) {
        const std::vector<NodeId> wanted =
            step(*s, h, cut, view, revealed, concealed, paged->stats().memory_short);
        ASSERT_EQ(cut.validate(h), "");
        for (const NodeId n : cut.nodes()) ASSERT_GT(h.arrays().point_count[n], 0u) << n;
        revealed.clear(), concealed.clear();
        // As the stage does (FeedbackStage, follow_pages).
        paged->request(paged->rank(wanted, view));
        const PagedHierarchy::ListHolds holds[] = {[&](NodeId n) { return cut.contains(n); }};
        paged->evict(holds, &concealed);
        short_count += paged->stats().memory_short;
        ASSERT_TRUE(paged->wait_idle(kWaitMs));
        paged->publish(&revealed);
        most = std::max(most, paged->stats().resident_bytes);
      }
    }
    const PagingStats st = paged->stats();
    EXPECT_LE(most, options.memory_bytes);
    // bucket's depths are the light's, not the view's: its cut stays where
    // the light puts it, within what the budget lets it read.
    if (std::string(name) != "bucket") {
      EXPECT_GT(st.evicted, 0u);
    }
    EXPECT_GT(short_count, 0) << "the budget is short of what the flight wants";
    EXPECT_GT(st.loaded, st.evicted);
    EXPECT_EQ(st.failed, 0u);
    // Every resident node is reachable: nothing of a page given back is
    // left in the tree.
    EXPECT_EQ(reachable(h).size(), st.resident_nodes);
    // The memory pages under the arrays: the resident nodes' and the rest
    // of those at the ends of their runs, not those of the runs given back
    // (each one's ends stayed before their pages were counted: 2.5-2.9
    // times the resident bytes here, now 1.1-1.3).
    EXPECT_LE(paged->held_bytes(), st.resident_bytes * 3 / 2);
  }
}

// Two runs of values on one memory page: a counted array gives the page
// back with the second run; an alone one keeps it (zeros) for good.
TEST(ReservedArray, AMemoryPageRunsShareGoesBackWithTheLastOfThem) {
  const auto page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  for (const PageSharing sharing : {PageSharing::counted, PageSharing::alone}) {
    SCOPED_TRACE(sharing == PageSharing::counted ? "counted" : "alone");
    const ReservedArray<std::uint8_t> a(4 * page, sharing);
    // [0, page / 2) and [page / 2, 3 page / 2): memory pages 0 and 1.
    a.use(0, page / 2);
    a.use(page / 2, page);
    std::memset(a.data(), 7, page + page / 2);
    EXPECT_EQ(a.held_bytes(4 * page), 2 * page);
    a.release(0, page / 2);
    EXPECT_EQ(a[0], 0);
    EXPECT_EQ(a[page / 2], 7) << "the other run's values stay";
    EXPECT_EQ(a.held_bytes(4 * page), 2 * page);
    a.release(page / 2, page);
    // (Before reading: a read maps the system's page of zeros, which
    // mincore counts.)
    EXPECT_EQ(a.held_bytes(4 * page), sharing == PageSharing::counted ? 0 : 2 * page);
    EXPECT_EQ(a[page / 2], 0);
  }
}

// A page corrupted on disk: one line naming the file and the page, its
// parent stays a leaf, everything else is read and drawn.
TEST(PagedHierarchy, ACorruptedPageIsNamedAndTheRestIsDrawn) {
  const fs::path cache = terrain_cache("paged_corrupt");
  {
    std::fstream f(cache, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(0, std::ios::end);
    const auto size = static_cast<std::streamoff>(f.tellg());
    f.seekp(size - 9);  // the last page's last byte (the checksum follows)
    char byte = 0;
    f.seekg(size - 9), f.read(&byte, 1);
    byte = static_cast<char>(byte ^ 0x20);
    f.seekp(size - 9), f.write(&byte, 1);
  }
  const auto paged = PagedHierarchy::open(cache);
  test::load_every_page(*paged);
  const std::vector<std::string> problems = paged->take_problems();
  ASSERT_EQ(problems.size(), 1u);
  const PagingStats s = paged->stats();
  EXPECT_NE(problems[0].find("t.tch"), std::string::npos) << problems[0];
  EXPECT_NE(problems[0].find("page " + std::to_string(s.pages - 1) + " of " +
                             std::to_string(s.pages) + ": checksum mismatch (corrupted)"),
            std::string::npos)
      << problems[0];
  EXPECT_EQ(s.failed, 1u);
  EXPECT_LT(s.resident_pages, s.pages);
  EXPECT_GE(s.resident_pages + 4, s.pages) << "only the bad page's group is missing";
  EXPECT_EQ(TreeCut::leaf_cut(paged->hierarchy()).validate(paged->hierarchy()), "");
}

// The file cut short after it was opened: the pages past its end are named
// (changed while being read), never a crash.
TEST(PagedHierarchy, AFileThatShrinksIsNamedNotACrash) {
  const fs::path cache = terrain_cache("paged_shrink");
  const auto paged = PagedHierarchy::open(cache);
  fs::resize_file(cache, fs::file_size(cache) / 2);
  test::load_every_page(*paged);
  const std::vector<std::string> problems = paged->take_problems();
  ASSERT_FALSE(problems.empty());
  for (const std::string& p : problems) EXPECT_NE(p.find("got shorter"), std::string::npos) << p;
  EXPECT_EQ(TreeCut::leaf_cut(paged->hierarchy()).validate(paged->hierarchy()), "");
}

// The Feedback Stage drives a paged model as the viewer will: pages
// published and asked for between iterations, what no list holds given
// back, the pages' counters in the iteration's; standing still its lists
// reach the cut of the model held whole.
TEST(PagedHierarchy, TheFeedbackStageDrawsAPagedModelToTheWholeModelsCut) {
  const fs::path cache = terrain_cache("paged_stage");
  std::string why;
  const std::optional<Hierarchy> whole = load_cache(cache, std::nullopt, &why);
  ASSERT_TRUE(whole) << why;
  const ViewSnapshot view = patch_view(-0.3f, 0.2f);
  const StrategyRegistry registry = strategies::builtin_registry();
  for (const char* name : {"recursive", "event_queue"}) {
    SCOPED_TRACE(name);
    const std::vector<NodeId> expect = sorted(settle(*registry.create(name), *whole, view));
    PagingOptions options;
    options.memory_bytes = 64u << 20;
    std::shared_ptr<PagedHierarchy> paged = PagedHierarchy::open(cache, options);
    StageOptions manual;
    manual.launch = Launch::Manual;
    manual.validate = true;
    FeedbackStage stage(make_paged_model(paged), registry.create(name), manual);
    stage.set_view(view);
    bool reached = false;
    for (int frame = 0; frame < 400 && !reached; ++frame) {
      const FrameLists f = stage.poll();
      if (f.exchanged) {
        std::vector<NodeId> got(f.current.nodes.begin(), f.current.nodes.end());
        reached = got == expect;
      }
      stage.step();
      // (A frame never waits for the disk; this test waits so that its
      // frames are not over before one page is read.)
      ASSERT_TRUE(paged->wait_idle(kWaitMs));
    }
    EXPECT_TRUE(reached) << "the lists never reached the whole model's cut";
    EXPECT_EQ(stage.counters().errors, 0u) << stage.counters().last_error;
    const Counters& c = stage.counters().last.counters;
    ASSERT_TRUE(c.find("pages_resident"));
    EXPECT_EQ(*c.find("pages_resident"), double(paged->stats().resident_pages));
    EXPECT_GT(*c.find("pages_loaded"), 0.0);
    EXPECT_EQ(*c.find("pages_failed"), 0.0);
  }
}

// A page is given back only when no list reaches into it: an older, coarser
// cut still drawn (above the page) does not free what the newer cut holds.
TEST(PagedHierarchy, APageOneListReachesIntoIsNotGivenBack) {
  const fs::path cache = terrain_cache("paged_two_lists");
  const auto probe = PagedHierarchy::open(cache);
  test::load_every_page(*probe);
  PagingOptions options;
  options.memory_bytes = probe->stats().resident_bytes - 1;  // not all of it fits
  const auto paged = PagedHierarchy::open(cache, options);
  test::load_every_page(*paged);
  const Hierarchy& h = paged->hierarchy();
  const std::uint64_t resident = paged->stats().resident_pages;
  ASSERT_GT(resident, 2u);
  std::vector<NodeId> hidden;
  for (const NodeId n : reachable(h))
    if (paged->hidden(n)) hidden.push_back(n);
  ASSERT_FALSE(hidden.empty());
  paged->request(hidden);  // what does not fit: evict() is to make room
  const TreeCut coarse = TreeCut::root_cut(h);
  const TreeCut fine = TreeCut::leaf_cut(h);
  const PagedHierarchy::ListHolds both[] = {[&](NodeId n) { return coarse.contains(n); },
                                            [&](NodeId n) { return fine.contains(n); }};
  EXPECT_EQ(paged->evict(both), 0u) << "the fine cut reaches into every page";
  EXPECT_EQ(paged->stats().resident_pages, resident);
  for (const NodeId n : fine.nodes()) ASSERT_GT(h.arrays().point_count[n], 0u);
  const PagedHierarchy::ListHolds coarse_only[] = {both[0]};
  EXPECT_GT(paged->evict(coarse_only), 0u) << "the root cut alone uses no page below the root";
  EXPECT_LT(paged->stats().resident_pages, resident);
}

// The event queue under a budget, its pages arriving a few at a time while
// it flies: nodes that gain or lose their children (revealed, concealed)
// while they hold a place in its queue must leave it, or a later fold erases
// another node's entry (a cut listing a node twice; a crash under TSan).
// The flight and the budget of paging_bench, on the test's terrain. Its
// records follow the pages: one for each resident node after every
// iteration, given back with the pages (a record for every node of the
// hierarchy was 32 B a node of the file).
TEST(PagedHierarchy, TheEventQueueFollowsPagesThatComeAndGo) {
  const fs::path cache = terrain_cache("paged_event_queue");
  const Hierarchy& whole = *test::small_hierarchy(tools::ModelKind::Terrain, 100000);
  for (const int every : {1, 2, 3, 5}) {
    SCOPED_TRACE(every);
    PagingOptions options;
    options.memory_bytes =
        std::uint64_t(whole.node_count()) * PagedHierarchy::open(cache)->bytes_per_node() / 8;
    const auto paged = PagedHierarchy::open(cache, options);
    const Hierarchy& h = paged->hierarchy();
    const std::unique_ptr<Strategy> s = strategies::builtin_registry().create("event_queue");
    const auto& queue = dynamic_cast<const strategies::EventQueueStrategy&>(*s);
    s->reset(h);
    TreeCut cut = TreeCut::root_cut(h);
    std::vector<NodeId> revealed, concealed;
    std::size_t most = 0;
    const glm::vec3 lo = h.bounds_min(), hi = h.bounds_max();
    const float ext = glm::length(hi - lo);
    for (int f = 0; f < 200; ++f) {
      const float t = float(f) / 199.0f;
      const glm::vec3 eye(lo.x + (hi.x - lo.x) * (0.1f + 0.8f * t),
                          lo.y + (hi.y - lo.y) * (0.15f + 0.7f * t), hi.z + 0.1f * ext);
      const glm::vec3 ahead = glm::normalize(glm::vec3(hi.x - lo.x, 0.875f * (hi.y - lo.y), 0.0f));
      ViewSnapshot view =
          ViewSnapshot::look_at(eye, eye + 0.2f * ext * ahead - glm::vec3(0.0f, 0.0f, 0.15f * ext),
                                {1280, 720}, 0.9f, 0.001f * ext, 4.0f * ext);
      view.version = static_cast<std::uint64_t>(f) + 1;
      const std::vector<NodeId> wanted = step(*s, h, cut, view, revealed, concealed);
      ASSERT_EQ(cut.validate(h), "") << "frame " << f;
      ASSERT_EQ(queue.records(), reachable(h).size()) << "frame " << f;
      most = std::max(most, queue.records());
      revealed.clear(), concealed.clear();
      const PagedHierarchy::ListHolds holds[] = {[&](NodeId n) { return cut.contains(n); }};
      paged->evict(holds, &concealed);
      paged->request(paged->rank(wanted, view, 4));
      if (f % every == 0) {
        ASSERT_TRUE(paged->wait_idle(kWaitMs));
      }
      paged->publish(&revealed);
    }
    EXPECT_GT(paged->stats().evicted, 0u);
    EXPECT_LT(most, h.node_count() / 4) << "records for nodes the budget never held";
  }
}
