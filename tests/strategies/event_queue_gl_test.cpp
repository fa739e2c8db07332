// Event-driven refinement (Zach & Karner 2003) against its top-down baseline:
// after every iteration along camera paths (slow, fast, rotating, flying
// through the model, teleports) the cut of `event_queue` equals the cut of
// `topdown` under the same view, node for node, and is valid; also after a
// cancelled iteration, a parameter change and a static camera. The CLI
// renders both with --sync to the same cut sizes and the same frames.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <span>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "strategy_fixtures.hpp"
#include "test_support.hpp"
#include "treecut/strategies/event_queue.hpp"
#include "treecut/strategies/refinement_criterion.hpp"
#include "treecut/strategies/topdown.hpp"

namespace treecut::test {
namespace {

using strategies::EventQueueStrategy;
using strategies::TopDownStrategy;

// One strategy with its own cut, driven like the stage drives it.
template <class S>
struct Runner {
  explicit Runner(const Hierarchy& hierarchy) : h(hierarchy), cut(TreeCut::root_cut(hierarchy)) {
    s.reset(hierarchy);
  }
  IterationResult step(const ViewSnapshot& view, const std::atomic<bool>* cancel = nullptr) {
    return iterate_once(s, h, cut, view, cancel);
  }
  [[nodiscard]] std::vector<NodeId> sorted() const {
    std::vector<NodeId> v(cut.nodes().begin(), cut.nodes().end());
    std::sort(v.begin(), v.end());
    return v;
  }
  const Hierarchy& h;
  S s;
  TreeCut cut;
};

struct Scene {
  glm::vec3 center;
  float extent;
};

Scene scene_of(const Hierarchy& h) {
  return {0.5f * (h.bounds_min() + h.bounds_max()), glm::length(h.bounds_max() - h.bounds_min())};
}

// A random camera of the brute-force bound tests: the eye 0.3 to 0.8 extents
// from the center in any direction, the target within 0.2 extents of it.
struct EyeAndTarget {
  glm::vec3 eye;
  glm::vec3 target;
};
EyeAndTarget random_camera(const Scene& s, std::mt19937& rng,
                           std::uniform_real_distribution<double>& u) {
  const glm::vec3 eye = s.center + float(0.3 + 0.5 * (u(rng) + 1.0)) * s.extent *
                                       glm::normalize(glm::vec3(u(rng), u(rng), u(rng)));
  const glm::vec3 target = s.center + 0.2f * s.extent * glm::vec3(u(rng), u(rng), u(rng));
  return {eye, target};
}

NodeId random_node(const Hierarchy& h, std::mt19937& rng) {
  return NodeId(std::uniform_int_distribution<std::uint32_t>(0, h.node_count() - 1)(rng));
}

ViewSnapshot camera(const Scene& s, glm::vec3 eye, glm::vec3 target, std::uint64_t version,
                    float fov = 0.8f, glm::ivec2 viewport = {640, 480}) {
  ViewSnapshot v =
      ViewSnapshot::look_at(eye, target, viewport, fov, 0.001f * s.extent, 20.0f * s.extent);
  v.version = version;
  v.frame = version;
  return v;
}

// The camera paths; rho is 0.002 diameters and omega 0.02 rad per frame.
std::vector<ViewSnapshot> make_path(const std::string& kind, const Scene& s) {
  std::vector<ViewSnapshot> path;
  const auto orbit_eye = [&](float angle, float dist) {
    return s.center + dist * s.extent * glm::vec3(std::cos(angle), 0.3f, std::sin(angle));
  };
  if (kind == "slow") {
    // Within rho and omega: one frame per iteration, closing in a little.
    for (int f = 0; f < 120; ++f) {
      const float dist = 0.9f - 0.0005f * float(f);
      path.push_back(camera(s, orbit_eye(0.0015f * float(f), dist), s.center, path.size() + 1));
    }
  } else if (kind == "fast") {
    // Up to ten times faster than rho and omega allow: several frames per iteration.
    for (int f = 0; f < 80; ++f) {
      const float dist = 0.8f + 0.3f * std::sin(0.1f * float(f));
      path.push_back(camera(s, orbit_eye(0.09f * float(f), dist), s.center, path.size() + 1));
    }
  } else if (kind == "rotating") {
    // A fixed eye near the model turning its head: nodes enter and leave the view.
    const glm::vec3 eye = orbit_eye(0.5f, 0.45f);
    for (int f = 0; f < 120; ++f) {
      const float a = 0.035f * float(f);
      const glm::vec3 dir(std::cos(a), 0.25f * std::sin(0.7f * a), std::sin(a));
      path.push_back(camera(s, eye, eye + dir, path.size() + 1));
    }
  } else if (kind == "flythrough") {
    // Straight through the model, looking ahead: the eye enters node spheres.
    const glm::vec3 dir = glm::normalize(glm::vec3(1.0f, -0.15f, 0.35f));
    for (int f = 0; f < 150; ++f) {
      const glm::vec3 eye = s.center + (-0.8f + 0.0107f * float(f)) * s.extent * dir;
      path.push_back(camera(s, eye, eye + dir, path.size() + 1));
    }
  } else if (kind == "sweep_fast") {
    // Strafing past the model, heading fixed, 0.03 extents a frame (15 rho):
    // back and forth.
    const glm::vec3 side = glm::normalize(glm::vec3(0.0f, 0.0f, 1.0f));
    for (int f = 0; f < 60; ++f) {
      const float t = float(f < 30 ? f : 60 - f) - 15.0f;
      const glm::vec3 eye =
          s.center + s.extent * glm::vec3(0.7f, 0.2f, 0.0f) + 0.03f * t * s.extent * side;
      path.push_back(camera(s, eye, eye + glm::vec3(-1.0f, -0.2f, 0.0f), path.size() + 1));
    }
  } else if (kind == "turn_fast") {
    // Turning in place at 0.09 rad a frame (4.5 omega), near the model.
    const glm::vec3 eye = orbit_eye(0.3f, 0.5f);
    for (int f = 0; f < 70; ++f) {
      const float a = 0.09f * float(f);
      path.push_back(
          camera(s, eye, eye + glm::vec3(std::cos(a), -0.2f, std::sin(a)), path.size() + 1));
    }
  } else if (kind == "zoom") {
    // The field of view 50 -> 35 degrees in 20 frames and back in 10, still
    // frames between; then the window resized (a new aspect, then a new
    // height: the cone and the pixel scale change without the field of view).
    const glm::vec3 eye = orbit_eye(0.8f, 0.7f);
    const auto fov = [](float t) { return 0.8727f + (0.6109f - 0.8727f) * t; };
    for (int f = 0; f <= 20; ++f)
      path.push_back(camera(s, eye, s.center, path.size() + 1, fov(f / 20.0f)));
    for (int f = 0; f < 5; ++f)
      path.push_back(camera(s, eye, s.center, path.size() + 1, fov(1.0f)));
    for (int f = 0; f <= 10; ++f)
      path.push_back(camera(s, eye, s.center, path.size() + 1, fov(1.0f - f / 10.0f)));
    path.push_back(camera(s, eye, s.center, path.size() + 1, fov(0.0f), {800, 480}));
    path.push_back(camera(s, eye, s.center, path.size() + 1, fov(0.0f), {800, 600}));
    path.push_back(camera(s, eye, s.center, path.size() + 1, fov(0.0f), {400, 300}));
  } else if (kind == "dolly") {
    // The viewer's mouse wheel: the distance times 0.88 a notch, all in one
    // frame, a notch every third frame; eight in, eight out.
    float dist = 0.9f;
    for (int notch = 0; notch < 16; ++notch) {
      dist *= notch < 8 ? 0.88f : 1.0f / 0.88f;
      for (int f = 0; f < 3; ++f)
        path.push_back(camera(s, orbit_eye(1.1f, dist), s.center, path.size() + 1));
    }
  } else if (kind == "zoom_while_moving") {
    // The slow orbit with the field of view breathing between 40 and 55 degrees.
    for (int f = 0; f < 80; ++f) {
      const float fov = 0.82f + 0.13f * std::sin(0.12f * float(f));
      path.push_back(
          camera(s, orbit_eye(0.002f * float(f), 0.75f), s.center, path.size() + 1, fov));
    }
  } else if (kind == "speed_changes") {
    // Slow, then a fast sweep round the model (30 rho a frame), then slow again.
    float angle = 0.0f;
    for (int f = 0; f < 90; ++f) {
      angle += (f >= 30 && f < 60) ? 0.1f : 0.0015f;
      path.push_back(camera(s, orbit_eye(angle, 0.8f), s.center, path.size() + 1));
    }
  } else if (kind == "accelerating") {
    // A sweep past the model speeding up from 1 to 32 rho a frame and
    // slowing down again: the translation unit follows the eye both ways.
    const glm::vec3 side(0.0f, 0.0f, 1.0f);
    float u = -0.6f;
    for (int f = 0; f < 100; ++f) {
      u += 0.002f * std::exp2(0.1f * float(f < 50 ? f : 100 - f));
      const glm::vec3 eye = s.center + s.extent * glm::vec3(0.7f, 0.2f, 0.0f) + u * s.extent * side;
      path.push_back(camera(s, eye, eye + glm::vec3(-1.0f, -0.2f, 0.0f), path.size() + 1));
    }
  } else if (kind == "teleport") {
    // Slow stretches between jumps across the model.
    for (int leg = 0; leg < 5; ++leg) {
      const float base = 2.5f * float(leg);  // 1.3 extents apart: > kSlots / 2 frames
      for (int f = 0; f < 12; ++f) {
        path.push_back(camera(s, orbit_eye(base + 0.003f * float(f), 0.7f + 0.2f * float(leg % 2)),
                              s.center, path.size() + 1));
      }
    }
  }
  return path;
}

// Each path with the choice of method off (adaptive = 0: the events every
// iteration, today's figure 7) and on.
using PathCase = std::tuple<std::string, int>;
class EventQueuePath : public ::testing::TestWithParam<PathCase> {};

TEST_P(EventQueuePath, event_queue_exact_vs_topdown) {
  const auto& [kind, adaptive] = GetParam();
  const auto h = small_hierarchy(tools::ModelKind::Terrain, 40000);
  const Scene s = scene_of(*h);
  Runner<TopDownStrategy> top(*h);
  Runner<EventQueueStrategy> ev(*h);
  ev.s.set_param("adaptive", adaptive);
  // The paths of the issue 31 (the fast motions and the lens) with a coarser
  // threshold, so that their cuts stay partial.
  const bool old_path = kind == "slow" || kind == "fast" || kind == "rotating" ||
                        kind == "flythrough" || kind == "teleport";
  if (!old_path) {
    top.s.set_param("theta", 12.0);
    ev.s.set_param("theta", 12.0);
  }
  const auto path = make_path(kind, s);
  ASSERT_FALSE(path.empty());
  using Method = EventQueueStrategy::Method;
  std::uint64_t top_tests = 0, event_tests = 0, multi_frame = 0, rebuilds = 0, advances = 0;
  std::uint64_t passes = 0, changes = 0, rescaled_up = 0, rescaled_down = 0;
  double unit = 0.0, widest = 0.0;
  // The work of each, in top-down tests: an event costs event_cost tests, a
  // rebuild's test three (a test, the event time, the list insert).
  double cost = 0.0;
  const double kappa = ev.s.param("event_cost");
  std::size_t largest = 0;
  for (std::size_t i = 0; i < path.size(); ++i) {
    const IterationResult rt = top.step(path[i]);
    const IterationResult re = ev.step(path[i]);
    ASSERT_FALSE(re.cancelled);
    ASSERT_TRUE(re.converged);
    ASSERT_EQ(TreeCut::validate(*h, ev.cut.nodes()), "") << "frame " << i;
    ASSERT_EQ(ev.sorted(), top.sorted()) << kind << " frame " << i << ": event_queue "
                                         << ev.cut.size() << " nodes, topdown " << top.cut.size();
    const auto& st = ev.s.stats();
    ASSERT_EQ(st.rebuilt, st.method == Method::kRebuild) << "frame " << i;
    if (adaptive == 0) {
      ASSERT_NE(st.method, Method::kTopDown) << "frame " << i;
    }
    if (i > 0) {
      top_tests += rt.visited;
      event_tests += re.visited;
      cost += double(re.visited) * (st.method == Method::kEvents    ? kappa
                                    : st.method == Method::kRebuild ? 3.0
                                                                    : 1.0);
    }
    if (st.rescaled) {
      // Only by a factor of 2 or more.
      ASSERT_TRUE(st.unit >= 2.0 * unit || st.unit <= 0.5 * unit) << "frame " << i;
      (st.unit > unit ? rescaled_up : rescaled_down) += 1;
    }
    if (st.method != Method::kNone) unit = st.unit;
    widest = std::max(widest, unit);
    rebuilds += st.rebuilt ? 1 : 0;
    passes += st.method == Method::kTopDown ? 1 : 0;
    advances += st.method == Method::kEvents || st.method == Method::kNone ? 1 : 0;
    if (st.method == Method::kEvents) {
      // The counters the benchmark reports agree with the iteration's: an
      // advance refines only by unfolds, every fold coarsens at least once,
      // and the children tested at once are among the tests, at most as
      // many as the unfolded nodes' children.
      ASSERT_EQ(re.refined, st.unfolded) << "frame " << i;
      ASSERT_LE(st.unfolded, st.changed) << "frame " << i;
      ASSERT_LE(st.changed - st.unfolded, re.coarsened) << "frame " << i;
      ASSERT_LE(st.descended + st.rotation_events, re.visited) << "frame " << i;
      ASSERT_LE(st.descended, 4 * st.unfolded) << "frame " << i;  // 2 to 4 children a node
      changes += st.changed;
      multi_frame += st.frames_advanced > 1 ? 1 : 0;
    }
    if (st.method == Method::kNone) {
      ASSERT_EQ(re.visited, 0u) << "frame " << i;
    }
    largest = std::max(largest, ev.cut.size());
  }
  // The cut is not trivial.
  EXPECT_GT(largest, 2000u);
  const bool lens = kind == "zoom" || kind == "dolly" || kind == "zoom_while_moving";
  if (kind == "slow") {
    // Within rho and omega the events alone, far cheaper than the passes.
    EXPECT_EQ(rebuilds, 1u);  // only the first iteration
    EXPECT_EQ(passes, 0u);
    EXPECT_EQ(multi_frame, 0u);
    EXPECT_LT(event_tests * 5, top_tests) << "event tests " << event_tests << " top " << top_tests;
  }
  const double rho = ev.s.param("rho");
  if (kind == "slow" || kind == "rotating" || kind == "turn_fast") {
    EXPECT_DOUBLE_EQ(widest, rho) << kind;  // a slow or still eye: rho
  }
  if (kind == "accelerating") {
    // The unit followed the eye up to 32 rho a frame, and back down.
    EXPECT_GE(widest, 16.0 * rho);
    EXPECT_LE(unit, widest / 4.0);
    if (adaptive == 0) {
      EXPECT_GT(rescaled_up, 0u);
      EXPECT_GT(rescaled_down, 0u);
    }
  }
  if (adaptive == 0) {
    // The path really exercised the queue (not a rebuild per frame); a new
    // lens is motion, not a jump.
    EXPECT_GT(advances, path.size() / 2);
    if (kind != "slow" && kind != "zoom_while_moving") {
      EXPECT_GT(changes, 0u);
    }
    if (kind == "fast" || kind == "rotating") {
      EXPECT_GT(multi_frame, path.size() / 2);
    }
    if (kind == "teleport") {
      EXPECT_GE(rebuilds, 3u);
    }
    if (lens || kind == "sweep_fast" || kind == "turn_fast") {
      EXPECT_EQ(rebuilds, 1u);
    }
  } else {
    // The choice: never much dearer in tests than topdown's passes, and the
    // passes only where the camera is fast.
    EXPECT_LE(cost, 1.1 * double(top_tests) + 3.0 * double(largest)) << kind;
    if (kind == "sweep_fast" || kind == "turn_fast" || kind == "speed_changes" ||
        kind == "teleport") {
      EXPECT_GT(passes, 0u) << kind;
    }
    if (kind == "speed_changes") {
      // Slow, fast, slow: the events, the passes, one rebuild, the events.
      EXPECT_LE(rebuilds, 3u);
      const auto& st = ev.s.stats();
      EXPECT_EQ(st.method, Method::kEvents);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Paths, EventQueuePath,
    ::testing::Combine(::testing::Values("slow", "fast", "rotating", "flythrough", "teleport",
                                         "sweep_fast", "turn_fast", "zoom", "dolly",
                                         "zoom_while_moving", "speed_changes", "accelerating"),
                       ::testing::Values(0, 1)),
    [](const ::testing::TestParamInfo<PathCase>& p) {
      return std::get<0>(p.param) + (std::get<1>(p.param) != 0 ? "_adaptive" : "_events");
    });

// A random walk with every speed, a second model, parameter changes, zooms
// and new window sizes, with the choice of method off and on: still equal
// after every iteration.
TEST(EventQueue, event_queue_exact_vs_topdown_random_walk_and_params) {
  const auto h = small_hierarchy(tools::ModelKind::City, 30000);
  const Scene s = scene_of(*h);
  for (const int adaptive : {0, 1}) {
    Runner<TopDownStrategy> top(*h);
    Runner<EventQueueStrategy> ev(*h);
    ev.s.set_param("adaptive", adaptive);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    glm::vec3 eye = s.center + glm::vec3(0.6f * s.extent, 0.2f * s.extent, 0.1f * s.extent);
    glm::vec3 dir = glm::normalize(s.center - eye);
    float fov = 0.8f;
    glm::ivec2 window{640, 480};
    std::set<EventQueueStrategy::Method> methods;
    for (int i = 0; i < 200; ++i) {
      const float speed = (i % 37 == 0) ? 0.4f : (i % 5 == 0 ? 0.02f : 0.001f);
      eye += speed * s.extent * glm::vec3(u(rng), u(rng), u(rng));
      dir = glm::normalize(dir + ((i % 3 == 0) ? 0.3f : 0.01f) * glm::vec3(u(rng), u(rng), u(rng)));
      if (i % 7 == 0) fov = std::clamp(fov + 0.15f * u(rng), 0.5f, 1.1f);
      if (i % 29 == 0)
        window = {int(480 + 320 * (u(rng) + 1.0f)), int(360 + 240 * (u(rng) + 1.0f))};
      if (i == 80 || i == 140) {
        const double theta = i == 80 ? 3.0 : 0.8;
        top.s.set_param("theta", theta);
        ev.s.set_param("theta", theta);
      }
      if (i == 110) ev.s.set_param("omega", 0.05);
      const ViewSnapshot v = camera(s, eye, eye + dir, std::uint64_t(i) + 1, fov, window);
      top.step(v);
      ev.step(v);
      ASSERT_EQ(ev.sorted(), top.sorted()) << "adaptive " << adaptive << " iteration " << i;
      methods.insert(ev.s.stats().method);
    }
    EXPECT_TRUE(methods.count(EventQueueStrategy::Method::kEvents));
    EXPECT_EQ(methods.count(EventQueueStrategy::Method::kTopDown), adaptive != 0 ? 1u : 0u);
  }
}

// TreeCut::refine_known / coarsen_known (what the event queue edits the cut
// with, from its copies of the children's ranges) make the very list and
// slot map that refine / coarsen make, position for position.
TEST(EventQueue, known_children_edits_equal_refine_and_coarsen) {
  const auto h = small_hierarchy(tools::ModelKind::Terrain, 5000);
  TreeCut a = TreeCut::root_cut(*h), b = TreeCut::root_cut(*h);
  std::mt19937 rng(5);
  std::size_t refined = 0, coarsened = 0;
  for (int step = 0; step < 2000; ++step) {
    const std::span<const NodeId> nodes = a.nodes();
    const NodeId n = nodes[std::uniform_int_distribution<std::size_t>(0, nodes.size() - 1)(rng)];
    if (step % 3 != 2) {
      if (h->is_leaf(n)) continue;
      ASSERT_TRUE(a.refine(*h, n));
      b.refine_known(n, h->first_child(n), h->child_count(n));
      ++refined;
    } else {
      if (n == h->root()) continue;
      const NodeId p = h->parent(n);
      if (!a.can_coarsen(*h, p)) continue;
      ASSERT_TRUE(a.coarsen(*h, p));
      b.coarsen_known(p, h->first_child(p), h->child_count(p));
      ++coarsened;
    }
    ASSERT_TRUE(std::equal(a.nodes().begin(), a.nodes().end(), b.nodes().begin(), b.nodes().end()))
        << "step " << step;
  }
  EXPECT_GT(refined, 100u);
  EXPECT_GT(coarsened, 20u);
  EXPECT_EQ(TreeCut::validate(*h, b.nodes()), "");
  for (NodeId n = 0; n < h->node_count(); ++n) ASSERT_EQ(a.contains(n), b.contains(n)) << n;
  EXPECT_EQ(a.refinements(), b.refinements());
  EXPECT_EQ(a.coarsenings(), b.coarsenings());
}

TEST(EventQueue, static_camera_costs_nothing) {
  const auto h = small_hierarchy(tools::ModelKind::Terrain, 40000);
  const Scene s = scene_of(*h);
  Runner<EventQueueStrategy> ev(*h);
  const glm::vec3 eye = s.center + glm::vec3(0.7f, 0.3f, 0.2f) * s.extent;
  ev.step(camera(s, eye, s.center, 1));
  ASSERT_GT(ev.cut.size(), 1000u);
  const std::vector<NodeId> before = ev.sorted();
  // Same view version: nothing at all is tested.
  IterationResult r = ev.step(camera(s, eye, s.center, 1));
  EXPECT_EQ(r.visited, 0u);
  EXPECT_TRUE(r.converged);
  // A new version with the same camera (the light moved): no frame passes.
  r = ev.step(camera(s, eye, s.center, 2));
  EXPECT_EQ(r.visited, 0u);
  EXPECT_EQ(ev.s.stats().frames_advanced, 0u);
  EXPECT_FALSE(ev.s.stats().rebuilt);
  EXPECT_EQ(ev.sorted(), before);
  // The event state: a 32-byte record per node plus 4 bytes per queued event
  // (the lists keep their capacity, at most twice what they ever held).
  static_assert(EventQueueStrategy::kBytesPerNode == 32 && EventQueueStrategy::kBytesPerEvent == 4);
  const std::size_t queued = ev.s.stats().queued;
  EXPECT_GT(queued, ev.cut.size() / 2);
  EXPECT_GE(ev.s.state_bytes(), 32u * h->node_count() + 4u * queued);
  EXPECT_LE(ev.s.state_bytes(), 32u * h->node_count() + 2u * 4u * 2u * queued);
  // While passes run (a camera too fast for the events), the same.
  for (int i = 1; i <= 4; ++i) {
    const glm::vec3 e = eye + 0.05f * float(i) * s.extent * glm::vec3(0.0f, 0.0f, 1.0f);
    ev.step(camera(s, e, s.center, 2 + std::uint64_t(i)));
  }
  ASSERT_EQ(ev.s.stats().method, EventQueueStrategy::Method::kTopDown);
  const glm::vec3 last = eye + 0.2f * s.extent * glm::vec3(0.0f, 0.0f, 1.0f);
  r = ev.step(camera(s, last, s.center, 7));
  EXPECT_EQ(r.visited, 0u);
  EXPECT_EQ(ev.s.stats().method, EventQueueStrategy::Method::kNone);
}

// The lists keep the storage of their busiest moment until a trim (every
// kTrimEvery iterations) gives back what is past four times what a list
// holds: after a big cut the camera moves away, the queue shrinks, and so
// does the lists' storage.
TEST(EventQueue, lists_give_back_the_storage_of_their_busiest_moment) {
  const auto h = small_hierarchy(tools::ModelKind::Terrain, 200000);
  const Scene s = scene_of(*h);
  Runner<EventQueueStrategy> ev(*h);
  const auto lists = [&] { return ev.s.state_bytes() - 32u * ev.s.records(); };
  std::uint64_t version = 1;
  const glm::vec3 near = s.center + glm::vec3(0.3f, 0.1f, 0.1f) * s.extent;
  for (std::uint64_t i = 0; i < EventQueueStrategy::kTrimEvery; ++i)
    ev.step(camera(s, near, s.center, version++));
  const std::size_t busiest = lists();
  const std::size_t queued = ev.s.stats().queued;
  ASSERT_GT(ev.cut.size(), 1000u);
  const glm::vec3 far = s.center + glm::vec3(0.3f, 0.1f, 40.0f) * s.extent;
  for (std::uint64_t i = 0; i < 2 * EventQueueStrategy::kTrimEvery; ++i)
    ev.step(
        camera(s, far + glm::vec3(0.0f, 0.0f, 0.001f * float(i)) * s.extent, s.center, version++));
  // (Here 678,240 bytes for 54,553 events, then 352,184 for 233: the lists
  // of fewer than kTrimFloor entries keep theirs.)
  EXPECT_LT(ev.s.stats().queued, queued / 10);
  EXPECT_LT(lists(), busiest * 3 / 5);
}

TEST(EventQueue, cancelled_iteration_leaves_a_valid_cut_and_recovers) {
  const auto h = small_hierarchy(tools::ModelKind::Terrain, 40000);
  const Scene s = scene_of(*h);
  Runner<TopDownStrategy> top(*h);
  Runner<EventQueueStrategy> ev(*h);
  std::atomic<bool> cancel{true};
  bool cancelled_once = false;
  std::set<EventQueueStrategy::Method> cancelled_in;
  for (int i = 0; i < 40; ++i) {
    // Fast steps so that an iteration has thousands of events.
    const glm::vec3 eye =
        s.center + (0.5f + 0.01f * float(i)) * s.extent *
                       glm::vec3(std::cos(0.15f * float(i)), 0.25f, std::sin(0.15f * float(i)));
    const ViewSnapshot v = camera(s, eye, s.center, std::uint64_t(i) + 1);
    // Every fourth, and the rebuild that follows the first cancel.
    const bool cancel_now = i % 4 == 1 || i == 2;
    const IterationResult r = ev.step(v, cancel_now ? &cancel : nullptr);
    top.step(v);
    ASSERT_EQ(TreeCut::validate(*h, ev.cut.nodes()), "") << "iteration " << i;
    if (r.cancelled) {
      cancelled_once = true;
      cancelled_in.insert(ev.s.stats().method);
      EXPECT_FALSE(r.converged);
    } else {
      ASSERT_EQ(ev.sorted(), top.sorted()) << "iteration " << i;
    }
  }
  EXPECT_TRUE(cancelled_once);
  // Cancelled in a rebuild, in a plain pass (the camera is too fast for the
  // events) and among the events.
  EXPECT_TRUE(cancelled_in.count(EventQueueStrategy::Method::kRebuild));
  EXPECT_TRUE(cancelled_in.count(EventQueueStrategy::Method::kTopDown));
}

// What the brute-force tests of the event times share: a 20,000-point
// sphere, a seeded generator of [-1, 1], rho and omega at their defaults
// (model units, radians).
struct BoundSetup {
  explicit BoundSetup(unsigned seed) : rng(seed) {}
  std::shared_ptr<const Hierarchy> h = small_hierarchy(tools::ModelKind::Sphere, 20000);
  Scene s = scene_of(*h);
  std::span<const glm::vec4> cr = h->arrays().center_radius;
  std::mt19937 rng;
  std::uniform_real_distribution<double> u{-1.0, 1.0};
  double diameter = 2.0 * double(h->radius(0));
  double rho = 0.002 * diameter;
  double omega = 0.02;
};

// Each event time is a lower bound: brute force over random nodes and random
// camera moves within k frames of rho and omega, the test never differs
// before the frame the event names.
TEST(EventQueue, event_times_are_lower_bounds) {
  BoundSetup setup(5);
  auto& [h, s, cr, rng, u, diameter, rho, omega] = setup;
  std::size_t checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const auto [eye, target] = random_camera(s, rng, u);
    const ViewSnapshot v0 = camera(s, eye, target, 1);
    const auto c0 = strategies::CriterionConstants::from_view(v0, 1.5);
    for (int k = 0; k < 200; ++k) {
      const NodeId n = random_node(*h, rng);
      const bool now = strategies::unfold_test(c0, cr[n]);
      const std::uint32_t t = now ? strategies::potential_fold_time(c0, cr[n], rho, omega, 511)
                                  : strategies::potential_unfold_time(c0, cr[n], rho, omega, 511);
      if (t < 2) continue;
      // A camera t - 1 frames away at full speed, straight at the node or
      // anywhere, turned by (t - 1) omega towards or away from it.
      const double frames = double(t - 1);
      const glm::dvec3 d = glm::dvec3(glm::vec3(cr[n])) - glm::dvec3(eye);
      for (int m = 0; m < 8; ++m) {
        glm::dvec3 move = m < 2 ? (m == 0 ? glm::normalize(d) : -glm::normalize(d))
                                : glm::normalize(glm::dvec3(u(rng), u(rng), u(rng)));
        const glm::vec3 e1 = glm::vec3(glm::dvec3(eye) + 0.999 * frames * rho * move);
        const glm::dvec3 fwd = glm::normalize(glm::dvec3(target - eye));
        glm::dvec3 axis =
            glm::normalize(glm::cross(fwd, m % 2 == 0 ? d : glm::dvec3(u(rng), u(rng), u(rng))));
        const double a = 0.999 * frames * omega * (m % 3 == 0 ? 1.0 : -1.0);
        const glm::dvec3 f1 = fwd * std::cos(a) + glm::cross(axis, fwd) * std::sin(a);
        const ViewSnapshot v1 = camera(s, e1, e1 + glm::vec3(f1), 2);
        const auto c1 = strategies::CriterionConstants::from_view(v1, 1.5);
        ASSERT_EQ(strategies::unfold_test(c1, cr[n]), now)
            << "node " << n << " event in " << t << " frames changed within " << frames;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 10000u);
}

// A camera move of the bound tests below: the eye `dist` towards the node
// (`d`, from the eye; every third m) or in a random direction, the view
// direction turned by `angle` about an axis across the node's direction
// (even m) or a random one, either way round (every other pair of m).
// Returns the new eye and a target ahead of it.
std::pair<glm::vec3, glm::vec3> moved_camera(glm::vec3 eye, glm::vec3 target, glm::dvec3 d,
                                             double dist, double angle, int m, std::mt19937& rng,
                                             std::uniform_real_distribution<double>& u) {
  const glm::dvec3 move =
      m % 3 == 0 ? glm::normalize(d) : glm::normalize(glm::dvec3(u(rng), u(rng), u(rng)));
  const glm::vec3 e1 = glm::vec3(glm::dvec3(eye) + dist * move);
  const glm::dvec3 fwd = glm::normalize(glm::dvec3(target - eye));
  const glm::dvec3 axis =
      glm::normalize(glm::cross(fwd, m % 2 == 0 ? d : glm::dvec3(u(rng), u(rng), u(rng))));
  const double a = angle * (m % 4 < 2 ? 1.0 : -1.0);
  const glm::dvec3 f1 = fwd * std::cos(a) + glm::cross(axis, fwd) * std::sin(a);
  return {e1, e1 + glm::vec3(f1)};
}

// The two clocks: while the eye has moved less than m rho AND the direction
// has turned less than w omega, the test cannot change, for any split of the
// visibility gap (the camera's pace) and any mix of the two motions: brute
// force over random nodes and moves up to just below both bounds.
TEST(EventQueue, two_clock_event_times_are_lower_bounds) {
  BoundSetup setup(7);
  auto& [h, s, cr, rng, u, diameter, rho, omega] = setup;
  const double paces[] = {0.0, 0.05, 1.0, 20.0};
  std::size_t checked = 0, rotation_bounded = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const auto [eye, target] = random_camera(s, rng, u);
    const auto c0 = strategies::CriterionConstants::from_view(camera(s, eye, target, 1), 1.5);
    const strategies::EventRates rates(c0, rho, omega, 511.0, 63.0, paces[trial % 4]);
    for (int k = 0; k < 100; ++k) {
      const NodeId n = random_node(*h, rng);
      const bool now = strategies::unfold_test(c0, cr[n]);
      const strategies::EventTime t = now ? strategies::potential_fold_event(c0, cr[n], rates)
                                          : strategies::potential_unfold_event(c0, cr[n], rates);
      if (t.m <= 0.0 && t.w <= 0.0) continue;
      rotation_bounded += std::isinf(t.w) ? 0 : 1;
      const glm::dvec3 d = glm::dvec3(glm::vec3(cr[n])) - glm::dvec3(eye);
      for (int m = 0; m < 8; ++m) {
        // Translation up to just below m rho (none when m is 0), rotation up
        // to just below w omega (half a turn when rotation cannot matter).
        const double f_m = m < 4 ? 0.999 : 0.999 * 0.5 * (u(rng) + 1.0);
        const double f_w = m % 2 == 0 ? 0.999 : 0.999 * 0.5 * (u(rng) + 1.0);
        const double dist = f_m * t.m * rho;
        const double angle = f_w * std::min(std::isinf(t.w) ? 1e9 : t.w * omega, 3.0);
        const auto [e1, t1] = moved_camera(eye, target, d, dist, angle, m, rng, u);
        const auto c1 = strategies::CriterionConstants::from_view(camera(s, e1, t1, 2), 1.5);
        ASSERT_EQ(strategies::unfold_test(c1, cr[n]), now)
            << "node " << n << " event (m " << t.m << ", w " << t.w << ") changed after "
            << dist / rho << " rho and " << angle / omega << " omega";
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 10000u);
  EXPECT_GT(rotation_bounded, 1000u);
}

// The lens as motion (issue 31): a zoom by e^z counts as a translation of
// z * reach on the translation clock, a new cone half-angle beta as a turn
// by the same angle on the rotation clock. While the eye's move plus the
// zoom's share stays below m rho AND the turn plus beta's change below
// w omega, the test cannot change: brute force over random nodes, zooms in
// and out, new aspects and window sizes, each budget split at random
// between the motion and the lens.
TEST(EventQueue, lens_event_times_are_lower_bounds) {
  BoundSetup setup(13);
  auto& [h, s, cr, rng, u, diameter, rho, omega] = setup;
  const glm::ivec2 windows[] = {{640, 480}, {800, 480}, {400, 300}, {1920, 1080}};
  std::size_t checked = 0, zoom_bounded = 0, cone_bounded = 0;
  for (int trial = 0; trial < 300; ++trial) {
    auto [eye, target] = random_camera(s, rng, u);
    if (trial % 2 == 1) {
      // Farther than the reach too (1 to 3 extents): there the zoom's bound
      // is scaled.
      eye = s.center +
            float(2.0 + u(rng)) * s.extent * glm::normalize(glm::vec3(u(rng), u(rng), u(rng)));
    }
    const float fov0 = float(0.6 + 0.3 * (u(rng) + 1.0));
    const auto c0 = strategies::CriterionConstants::from_view(camera(s, eye, target, 1, fov0), 1.5);
    const strategies::EventRates rates(c0, rho, omega, 511.0, 63.0, 1.0, diameter);
    for (int k = 0; k < 60; ++k) {
      const NodeId n = random_node(*h, rng);
      const bool now = strategies::unfold_test(c0, cr[n]);
      const strategies::EventTime t = now ? strategies::potential_fold_event(c0, cr[n], rates)
                                          : strategies::potential_unfold_event(c0, cr[n], rates);
      if (t.m <= 0.0) continue;
      for (int m = 0; m < 8; ++m) {
        // The lens first: a new field of view (zoom in or out) and window,
        // kept within its share of both budgets; the motion takes the rest.
        const double share = 0.5 * (u(rng) + 1.0);
        const double budget_m = 0.999 * t.m * rho;                            // model units
        const double budget_w = std::isinf(t.w) ? 3.0 : 0.999 * t.w * omega;  // radians
        const double z = share * budget_m / diameter * (m % 2 == 0 ? 1.0 : -1.0);
        float fov1 = float(2.0 * std::atan(std::tan(0.5 * fov0) * std::exp(z)));
        glm::ivec2 w1 = windows[m % 4];
        auto c1 =
            strategies::CriterionConstants::from_view(camera(s, eye, target, 2, fov1, w1), 1.5);
        double zoom = std::abs(std::log(c1.pixel_scale / c0.pixel_scale)) * diameter;
        double cone = std::abs(c1.beta - c0.beta);
        if (zoom >= share * budget_m || cone >= share * budget_w) {
          // The new window alone is over the share: the motion takes it all.
          fov1 = fov0;
          w1 = {640, 480};
          zoom = cone = 0.0;
        }
        if (zoom >= budget_m || cone >= budget_w) continue;
        const double dist = (budget_m - zoom) * 0.5 * (u(rng) + 1.0);
        const double angle = std::min(budget_w - cone, 3.0) * 0.5 * (u(rng) + 1.0);
        const glm::dvec3 d = glm::dvec3(glm::vec3(cr[n])) - glm::dvec3(eye);
        const auto [e1, t1] = moved_camera(eye, target, d, dist, angle, m, rng, u);
        const auto c2 =
            strategies::CriterionConstants::from_view(camera(s, e1, t1, 3, fov1, w1), 1.5);
        ASSERT_EQ(strategies::unfold_test(c2, cr[n]), now)
            << "node " << n << " event (m " << t.m << ", w " << t.w << ") changed after "
            << dist / rho << " rho, " << angle / omega << " omega and a lens of " << zoom / rho
            << " rho, " << cone / omega << " omega";
        ++checked;
        zoom_bounded += zoom > 0.3 * budget_m ? 1 : 0;
        cone_bounded += cone > 0.3 * budget_w ? 1 : 0;
      }
    }
  }
  EXPECT_GT(checked, 20000u);
  EXPECT_GT(zoom_bounded, 2000u);  // the zoom took a good part of the translation budget
  EXPECT_GT(cone_bounded, 500u);   // and the cone of the rotation budget
}

// decide() is the test and the event time of its result in one call, and
// must be exactly those (the queue uses it, the bound tests above check the
// two event functions): bit for bit, over random nodes (leaves, inner nodes,
// the eye inside spheres), cameras and paces.
TEST(EventQueue, decide_equals_test_and_event_time) {
  BoundSetup setup(9);
  auto& [h, s, cr, rng, u, diameter, rho, omega] = setup;
  const double paces[] = {0.0, 0.05, 1.0, 20.0};
  std::size_t passes = 0, fails = 0, inside = 0;
  for (int trial = 0; trial < 200; ++trial) {
    auto [eye, target] = random_camera(s, rng, u);
    if (trial % 5 == 0) eye = s.center + 0.05f * s.extent * glm::vec3(u(rng), u(rng), u(rng));
    const auto cam = strategies::CriterionConstants::from_view(camera(s, eye, target, 1), 1.5);
    // Every other camera with a reach (the zoom's exchange rate) shorter
    // than most distances, so the scaled threshold times are compared too.
    const double reach = trial % 2 == 0 ? std::numeric_limits<double>::infinity() : 0.2 * s.extent;
    const strategies::EventRates rates(cam, rho, 0.02, 511.0, 63.0, paces[trial % 4], reach);
    for (int k = 0; k < 200; ++k) {
      // Ids are breadth-first: every tenth node among the 64 largest spheres.
      const NodeId n = k % 10 == 0 ? random_node(*h, rng) % 64 : random_node(*h, rng);
      const strategies::Decision d = strategies::decide(cam, cr[n], rates);
      const bool pass = strategies::unfold_test(cam, cr[n]);
      ASSERT_EQ(d.pass, pass) << "node " << n;
      const strategies::EventTime t = pass ? strategies::potential_fold_event(cam, cr[n], rates)
                                           : strategies::potential_unfold_event(cam, cr[n], rates);
      ASSERT_EQ(d.t.m, t.m) << "node " << n;
      ASSERT_EQ(d.t.w, t.w) << "node " << n;
      (pass ? passes : fails) += 1;
      inside += glm::length(glm::vec3(cr[n]) - eye) < cr[n].w ? 1 : 0;
    }
  }
  EXPECT_GT(passes, 1000u);
  EXPECT_GT(fails, 1000u);
  EXPECT_GT(inside, 100u);
}

// The CLI: both strategies along the same path with --sync draw the same
// number of splats in every row of stats.csv and the same frames.
std::vector<std::string> column(const std::filesystem::path& csv, const std::string& name) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string f; std::getline(hs, f, ',');) header.push_back(f);
  const auto it = std::find(header.begin(), header.end(), name);
  if (it == header.end()) return {};
  const auto index = std::size_t(it - header.begin());
  std::vector<std::string> values;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::string f;
    for (std::size_t i = 0; i <= index && std::getline(ls, f, ','); ++i) {
    }
    values.push_back(f);
  }
  return values;
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Both along `path` (none: the default orbit) with --sync: the same number of
// splats in every row of stats.csv and the same frames.
void expect_same_renders(const std::string& name, const std::string& path_option) {
  const auto dir = scratch_dir(name);
  const auto r = run_treecut(
      "render --default-kind terrain --default-points 20000 --width 160 "
      "--height 96 --frames 24 --warmup 0 --sync -s event_queue -s topdown "
      "-p theta=1 " +
      path_option + " --out " + quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto a = column(dir / "out" / "event_queue" / "stats.csv", "splats_drawn");
  const auto b = column(dir / "out" / "topdown" / "stats.csv", "splats_drawn");
  ASSERT_EQ(a.size(), 24u) << r.out;
  EXPECT_EQ(a, b);
  std::set<std::string> sizes(a.begin(), a.end());
  EXPECT_GT(sizes.size(), 1u);  // the cut changed along the path
  int frames = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir / "out" / "event_queue")) {
    if (e.path().extension() != ".png") continue;
    const auto other = dir / "out" / "topdown" / e.path().filename();
    ASSERT_TRUE(std::filesystem::exists(other)) << other;
    EXPECT_EQ(slurp(e.path()), slurp(other)) << e.path().filename();
    ++frames;
  }
  EXPECT_EQ(frames, 24);
}

TEST(EventQueueCli, render_sync_event_queue_equals_topdown) {
  expect_same_renders("event_queue_render", "");
}

// A zoom (the field of view 50 -> 25 -> 60 degrees) while the eye drifts,
// over the generated terrain ([-1, 1]^2, z up): the lens is motion for the
// event times, not a rebuild.
TEST(EventQueueCli, render_sync_event_queue_equals_topdown_while_zooming) {
  const auto dir = scratch_dir("event_queue_zoom_path");
  const auto path = dir / "zoom.campath";
  {
    std::ofstream out(path);
    out << "treecut-camera-path 1\n"
           "0.0  0.0 -2.2 1.2   0 0 0   0 0 1   50\n"
           "1.0  0.2 -2.1 1.2   0 0 0   0 0 1   25\n"
           "2.0  0.4 -2.0 1.1   0 0 0   0 0 1   60\n";
    ASSERT_TRUE(out.good());
  }
  expect_same_renders("event_queue_render_zoom", "--path " + quote(path));
}

}  // namespace
}  // namespace treecut::test
