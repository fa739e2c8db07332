// Selection time per frame: event-driven refinement (event_queue) against the
// top-down adjustment (topdown), Zach & Karner 2003, section 4 ("we compared
// our mesh selection method with the top-down mesh adjustment procedure").
// Seven camera paths over the dragon, the lion and a generated 20 M-point
// terrain (a slow orbit, a flythrough, abrupt turns and teleports; and, each
// at three speeds, a sideways sweep, a turn in place, a zoom of the field of
// view and the mouse wheel's dolly); both strategies see the same view every frame (and must give
// the same cut: checked every frame). Time = thread CPU time of iterate(); each strategy runs the
// whole path on its own. theta is chosen per model so that the cut at the first frame holds about
// 150,000 nodes; rho = 0.002 model diameters and omega = 0.02 rad per frame.
//
//   selection_bench [--benchmark_filter=...]
//   TREECUT_SELECTION_CSV=DIR selection_bench   # also one CSV per model and path
//   python3 tests/bench/selection_plot.py DIR docs/plots   # SVG per path + tables
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_models.hpp"
#include "treecut/file_io.hpp"
#include "treecut/mix64.hpp"
#include "treecut/strategies/event_queue.hpp"
#include "treecut/strategies/topdown.hpp"

namespace treecut::bench {
namespace {

using strategies::EventQueueStrategy;
using strategies::TopDownStrategy;

const char* const kModels[] = {"dragon", "lion", "terrain20m"};
const char* const kPaths[] = {"orbit", "flythrough", "abrupt", "sweep", "turn", "zoom", "dolly"};
constexpr std::size_t kTargetCut = 150'000;

std::shared_ptr<const Hierarchy> model(int which) {
  static std::shared_ptr<const Hierarchy> models[3];
  if (!models[which]) {
    if (which == 2) {
      models[which] = generated(tools::ModelKind::Terrain, large_cloud_points());
    } else {
      const auto ply =
          test::shared_asset(which == 0 ? "dragon_vrip_normals.ply" : "lion_takanawa.ply");
      if (!ply) return nullptr;
      OpenOptions o;
      o.cache_path = cache_dir() / (std::string(kModels[which]) + ".tch");
      models[which] = std::make_shared<const Hierarchy>(open_model(*ply, o).hierarchy);
    }
  }
  return models[which];
}

double thread_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e9 + double(ts.tv_nsec);
}

struct Frame {
  glm::vec3 eye, target;
  std::string segment;
  float fov = 0.8f;  // vertical field of view, radians
};

// The up axis of the shared assets is y (dragon) or z (lion, terrain); the
// paths circle around the vertical axis `up` at the model's center.
std::vector<Frame> make_path(int which, const Hierarchy& h, glm::vec3 up) {
  const glm::vec3 c = 0.5f * (h.bounds_min() + h.bounds_max());
  const float diameter = 2.0f * h.radius(0);
  const glm::vec3 a = std::abs(up.x) < 0.5f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
  const glm::vec3 x = glm::normalize(glm::cross(up, a));
  const glm::vec3 y = glm::cross(up, x);
  const auto around = [&](float angle, float dist, float height) {
    return c + dist * diameter * (std::cos(angle) * x + std::sin(angle) * y) +
           height * diameter * up;
  };
  std::vector<Frame> path;
  if (which == 0) {
    // A slow orbit at 0.8 diameters: 0.0016 diameters and 0.002 rad a frame,
    // within rho and omega.
    for (int f = 0; f < 300; ++f) {
      path.push_back({around(0.002f * float(f), 0.8f, 0.25f), c, "orbit"});
    }
  } else if (which == 1) {
    // Flying in towards the model and over it, looking ahead and down, at
    // 0.0019 diameters a frame.
    const glm::vec3 start = around(0.6f, 0.75f, 0.3f);
    const glm::vec3 dir = glm::normalize(c + 0.05f * diameter * up - start);
    for (int f = 0; f < 400; ++f) {
      const glm::vec3 eye = start + 0.0019f * diameter * float(f) * dir;
      path.push_back({eye, eye + dir - 0.3f * up, "flythrough"});
    }
  } else if (which == 3) {
    // Sweep: strafing past the model, heading fixed, back and forth over a
    // diameter, at 0.004, 0.0125 and 0.033 diameters a frame (2, 6 and 16
    // rho; at 30 fps the last crosses the model in one second); 120 frames
    // each, one continuous camera.
    float u = 0.0f, dir = 1.0f;
    for (const float speed : {0.004f, 0.0125f, 0.033f}) {
      for (int f = 0; f < 120; ++f) {
        u += dir * speed;
        if (std::abs(u) > 0.5f) {
          dir = -dir;
          u = std::copysign(1.0f, u) - u;
        }
        const glm::vec3 eye = c + diameter * (0.8f * x + 0.25f * up + u * y);
        path.push_back({eye, eye - x - 0.3f * up, "sweep " + std::to_string(speed).substr(0, 6)});
      }
    }
  } else if (which == 4) {
    // Turning in place beside the model, panning back and forth across it
    // (1.2 rad either side of facing it), at 0.013, 0.026 and 0.052 rad a
    // frame (45, 90 and 180 degrees a second at 60 fps), 120 frames each.
    const glm::vec3 eye = around(0.0f, 0.7f, 0.2f);
    float yaw = 0.0f, dir = 1.0f;
    for (const float rate : {0.013f, 0.026f, 0.052f}) {
      for (int f = 0; f < 120; ++f) {
        yaw += dir * rate;
        if (std::abs(yaw) > 1.2f) {
          dir = -dir;
          yaw = std::copysign(2.4f, yaw) - yaw;
        }
        // Facing the model is -x; yaw turns about the vertical.
        const glm::vec3 look = -std::cos(yaw) * x + std::sin(yaw) * y - 0.2f * up;
        path.push_back({eye, eye + look, "turn " + std::to_string(rate).substr(0, 5)});
      }
    }
  } else if (which == 5) {
    // Zoom: the field of view 50 -> 35 degrees and back, each way over 120,
    // 60 and 30 frames, the eye still.
    const glm::vec3 eye = around(0.5f, 0.8f, 0.25f);
    for (const int frames : {120, 60, 30}) {
      const std::string name = "zoom " + std::to_string(frames) + "f";
      for (int f = 1; f <= 2 * frames; ++f) {
        const float t =
            f <= frames ? float(f) / float(frames) : float(2 * frames - f) / float(frames);
        path.push_back({eye, c, name, 0.8727f + (0.6109f - 0.8727f) * t});
      }
    }
  } else if (which == 6) {
    // Dolly: the viewer's mouse wheel (the distance times 0.88 a notch, all
    // in one frame), eight notches in and eight out, a notch every 8, 4 and
    // 2 frames; the frames between are still.
    float dist = 1.2f;
    for (const int every : {8, 4, 2}) {
      const std::string name = "dolly " + std::to_string(every) + "f";
      for (int notch = 0; notch < 16; ++notch) {
        dist *= notch < 8 ? 0.88f : 1.0f / 0.88f;
        for (int f = 0; f < every; ++f) path.push_back({around(0.9f, dist, 0.3f * dist), c, name});
      }
    }
  } else {
    // Abrupt: a fast turn of the head (0.06 rad a frame, three times omega),
    // then teleports every 10 frames with slow motion between them.
    const glm::vec3 eye = around(0.0f, 0.7f, 0.2f);
    for (int f = 0; f < 150; ++f) {
      const float t = 0.4f * std::sin(0.06f * float(f) / 0.4f);  // sweep back and forth
      const glm::vec3 to_c = glm::normalize(c - eye);
      const glm::vec3 side = glm::normalize(glm::cross(to_c, up));
      path.push_back({eye, eye + std::cos(t) * to_c + std::sin(t) * side, "fast turn"});
    }
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 6.2831853f);
    for (int jump = 0; jump < 10; ++jump) {
      const float angle = u(rng);
      for (int f = 0; f < 10; ++f) {
        path.push_back({around(angle + 0.001f * float(f), 0.8f, 0.25f), c,
                        f == 0 ? "teleport" : "after teleport"});
      }
    }
  }
  return path;
}

glm::vec3 up_of(int which) {
  return which == 0 ? glm::vec3(0, 1, 0) : glm::vec3(0, 0, 1);
}

ViewSnapshot view_of(const Hierarchy& h, const Frame& f, std::uint64_t version, glm::vec3 up) {
  const float diameter = 2.0f * h.radius(0);
  ViewSnapshot v;
  v.view = glm::lookAt(f.eye, f.target, up);
  v.projection = glm::perspective(f.fov, 1920.0f / 1080.0f, 0.0005f * diameter, 20.0f * diameter);
  v.viewport = {1920, 1080};
  v.version = version;
  v.finalize();
  return v;
}

template <class S>
struct Runner {
  explicit Runner(const Hierarchy& hierarchy) : h(hierarchy), cut(TreeCut::root_cut(hierarchy)) {
    s.reset(hierarchy);
  }
  IterationResult step(const ViewSnapshot& view, double* ns) {
    nodes.clear();
    IterationInput in{h, view, 0, nullptr, s.params_version()};
    IterationOutput out;
    out.cut = &cut;
    out.nodes = &nodes;
    out.queries = &queries;
    const double t0 = thread_ns();
    s.iterate(in, out);
    *ns = thread_ns() - t0;
    return out.result;
  }
  const Hierarchy& h;
  S s;
  TreeCut cut;
  std::vector<NodeId> nodes;
  std::vector<QueryRequest> queries;
};

// theta giving about kTargetCut nodes at the path's first view (bisection on
// a log scale with topdown).
double choose_theta(const Hierarchy& h, const ViewSnapshot& v) {
  double lo = 0.05, hi = 200.0;
  for (int i = 0; i < 24; ++i) {
    const double mid = std::sqrt(lo * hi);
    Runner<TopDownStrategy> r(h);
    r.s.set_param("theta", mid);
    double ns = 0;
    r.step(v, &ns);
    (r.cut.size() > kTargetCut ? lo : hi) = mid;
  }
  return std::sqrt(lo * hi);
}

// The cut as a set, whatever its order: a sum of mixed ids, so two cuts
// that differ in any node differ here but for a 2^-64 chance.
std::uint64_t fingerprint(const TreeCut& cut) {
  std::uint64_t sum = 0;
  for (const NodeId n : cut.nodes()) sum += splitmix64(n);
  return sum;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void BM_Selection(benchmark::State& state) {
  const int which = int(state.range(0));
  const int path_kind = int(state.range(1));
  const auto h = model(which);
  if (!h) {
    state.SkipWithError("model not available");
    return;
  }
  const glm::vec3 up = up_of(which);
  const std::vector<Frame> path = make_path(path_kind, *h, up);
  std::vector<ViewSnapshot> views;
  for (std::size_t i = 0; i < path.size(); ++i) views.push_back(view_of(*h, path[i], i + 1, up));
  const double theta = choose_theta(*h, views[0]);
  std::vector<double> top_ns, event_ns, cut, events, tests, advanced, changed, unfolded, descended;
  std::vector<std::uint64_t> top_cut;
  std::vector<std::string> segment;
  // TREECUT_SELECTION_REPEATS (default 3): runs of the whole path by both;
  // each frame's time is the median over the runs, so that a moment of
  // noise on the machine during one strategy's run does not decide a
  // segment's ratio.
  const char* rep_env = std::getenv("TREECUT_SELECTION_REPEATS");
  const int repeats = std::max(1, rep_env ? std::atoi(rep_env) : 3);
  for (auto _ : state) {
    std::vector<std::vector<double>> top_runs(views.size()), event_runs(views.size());
    for (int rep = 0; rep < repeats; ++rep) {
      Runner<TopDownStrategy> top(*h);
      Runner<EventQueueStrategy> ev(*h);
      top.s.set_param("theta", theta);
      ev.s.set_param("theta", theta);
      // TREECUT_SELECTION_OMEGA / _RHO: other bounds than the defaults (0.02
      // rad, 0.002 diameters per frame), to see what each costs.
      if (const char* o = std::getenv("TREECUT_SELECTION_OMEGA"))
        ev.s.set_param("omega", std::atof(o));
      if (const char* r = std::getenv("TREECUT_SELECTION_RHO")) ev.s.set_param("rho", std::atof(r));
      // TREECUT_SELECTION_ADAPTIVE=0: the events every iteration (no choice
      // of method); TREECUT_SELECTION_EVENT_COST: another cost of an event.
      if (const char* a = std::getenv("TREECUT_SELECTION_ADAPTIVE"))
        ev.s.set_param("adaptive", std::atof(a));
      if (const char* k = std::getenv("TREECUT_SELECTION_EVENT_COST"))
        ev.s.set_param("event_cost", std::atof(k));
      // TREECUT_SELECTION_FOLLOW: the translation unit's factor on the eye's
      // pace (0: rho only).
      if (const char* f = std::getenv("TREECUT_SELECTION_FOLLOW"))
        ev.s.set_param("follow", std::atof(f));
      for (auto* v : {&top_ns, &event_ns, &cut, &events, &tests, &advanced, &changed, &unfolded,
                      &descended}) {
        v->clear();
      }
      top_cut.clear();
      segment.clear();
      // Each strategy alone along the whole path, as the engine runs one:
      // run in turns on the same frame, each would start from caches the
      // other had just filled with its own nodes.
      for (std::size_t i = 0; i < views.size(); ++i) {
        double tn = 0;
        const IterationResult rt = top.step(views[i], &tn);
        top_runs[i].push_back(tn);
        tests.push_back(double(rt.visited));
        top_cut.push_back(fingerprint(top.cut));
      }
      for (std::size_t i = 0; i < views.size(); ++i) {
        double en = 0;
        const IterationResult re = ev.step(views[i], &en);
        if (fingerprint(ev.cut) != top_cut[i]) {
          throw std::runtime_error(std::string(kModels[which]) + "/" + kPaths[path_kind] +
                                   " frame " + std::to_string(i) + ": event_queue's cut (" +
                                   std::to_string(ev.cut.size()) + " nodes) is not topdown's");
        }
        const auto& st = ev.s.stats();
        event_runs[i].push_back(en);
        cut.push_back(double(ev.cut.size()));
        events.push_back(double(re.visited));
        // -1: a rebuild, -2: a plain top-down pass.
        advanced.push_back(st.rebuilt ? -1.0
                           : st.method == EventQueueStrategy::Method::kTopDown
                               ? -2.0
                               : double(st.frames_advanced));
        changed.push_back(double(st.changed));
        unfolded.push_back(double(st.unfolded));
        descended.push_back(double(st.descended));
        segment.emplace_back(path[i].segment);
      }
    }
    for (std::size_t i = 0; i < views.size(); ++i) {
      top_ns.push_back(median(top_runs[i]));
      event_ns.push_back(median(event_runs[i]));
    }
    state.SetIterationTime(1e-9 * median(event_ns));
  }
  // Frame 0 builds the first cut from the root for both: not a selection.
  const auto tail = [](const std::vector<double>& v) {
    return std::vector<double>(v.begin() + 1, v.end());
  };
  const double mt = median(tail(top_ns)), me = median(tail(event_ns));
  state.counters["theta"] = theta;
  state.counters["cut"] = median(tail(cut));
  state.counters["top_us"] = 1e-3 * mt;
  state.counters["event_us"] = 1e-3 * me;
  state.counters["ratio"] = me / mt;
  state.counters["top_tests"] = median(tail(tests));
  state.counters["events"] = median(tail(events));
  // Tests that changed the cut (unfolds and folds; the rest only rescheduled).
  state.counters["changed"] = median(tail(changed));
  // Of those, unfolds; and the children of unfolds tested at once (their
  // first event time), which the cut changes force as much as the changes.
  state.counters["unfolded"] = median(tail(unfolded));
  state.counters["descended"] = median(tail(descended));
  state.counters["ns_per_event"] = me / median(tail(events));
  // Issue 31's target: the ratio of the mean iteration times, per segment
  // (frame 0 left out), never above 1.05; the worst segment and the share of
  // iterations that ran a plain top-down pass.
  double worst = 0.0, passes = 0.0;
  std::vector<std::string> names(segment.begin() + 1, segment.end());
  std::sort(names.begin(), names.end());
  names.erase(std::unique(names.begin(), names.end()), names.end());
  for (const std::string& name : names) {
    double t = 0.0, e = 0.0;
    for (std::size_t i = 1; i < segment.size(); ++i) {
      if (segment[i] != name) continue;
      t += top_ns[i];
      e += event_ns[i];
    }
    worst = std::max(worst, e / t);
  }
  for (std::size_t i = 1; i < advanced.size(); ++i) passes += advanced[i] == -2.0 ? 1.0 : 0.0;
  state.counters["worst_segment"] = worst;
  state.counters["pass_share"] = passes / double(advanced.size() - 1);
  state.SetLabel(std::string(kModels[which]) + "/" + kPaths[path_kind]);
  if (const char* dir = std::getenv("TREECUT_SELECTION_CSV")) {
    std::ostringstream out;
    out << "frame,segment,cut,topdown_us,event_queue_us,topdown_tests,events,frames_advanced,"
           "theta,changed,unfolded,descended\n";
    for (std::size_t i = 0; i < cut.size(); ++i) {
      out << i << ',' << segment[i] << ',' << cut[i] << ',' << 1e-3 * top_ns[i] << ','
          << 1e-3 * event_ns[i] << ',' << tests[i] << ',' << events[i] << ',' << advanced[i] << ','
          << theta << ',' << changed[i] << ',' << unfolded[i] << ',' << descended[i] << '\n';
    }
    try {
      treecut::write_file_atomically(
          std::string(dir) + "/" + kModels[which] + "_" + kPaths[path_kind] + ".csv", out.str());
    } catch (const std::exception& e) {
      state.SkipWithError(e.what());
    }
  }
}
BENCHMARK(BM_Selection)
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2, 3, 4, 5, 6}})
    ->ArgNames({"model", "path"})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

// A static camera: a new view version with the same eye and direction (the
// light moved). Nothing is due: O(1), independent of the cut size.
void BM_StaticCamera(benchmark::State& state) {
  const auto h = model(0);
  if (!h) {
    state.SkipWithError("model not available");
    return;
  }
  const glm::vec3 up = up_of(0);
  const std::vector<Frame> path = make_path(0, *h, up);
  const ViewSnapshot first = view_of(*h, path[0], 1, up);
  Runner<EventQueueStrategy> ev(*h);
  ev.s.set_param("theta", double(state.range(0)) / 100.0);
  double ns = 0;
  ev.step(first, &ns);
  ViewSnapshot v = first;
  double total = 0;
  std::uint64_t n = 0;
  for (auto _ : state) {
    v.version += 1;
    ev.step(v, &ns);
    total += ns;
    ++n;
  }
  state.counters["cut"] = double(ev.cut.size());
  state.counters["ns_per_iteration"] = total / double(n);
  state.counters["state_bytes_per_node"] = double(ev.s.state_bytes()) / double(h->node_count());
}
BENCHMARK(BM_StaticCamera)->Arg(2000)->Arg(200)->Arg(60)->Arg(25);

}  // namespace
}  // namespace treecut::bench

BENCHMARK_MAIN();
