// The `budget` strategy (Peng & Cao, I3D 2013, sections 5 and 6, on the CPU
// cores): what it does and what it adds, budget_strategy.hpp.
#include "treecut/strategies/budget_strategy.hpp"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <stdexcept>
#include <string>

namespace treecut::strategies {

namespace {

using Clock = std::chrono::steady_clock;

std::uint64_t ns_since(Clock::time_point& t) {
  const Clock::time_point now = Clock::now();
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now - t).count();
  t = now;
  return static_cast<std::uint64_t>(ns);
}

// CPU time of the calling thread and the pool's workers, nanoseconds.
std::uint64_t pool_cpu_ns(const WorkerPool& pool) {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000'000u +
         static_cast<std::uint64_t>(ts.tv_nsec) + pool.worker_cpu_ns();
}
std::uint64_t cpu_since(const WorkerPool& pool, std::uint64_t& t) {
  const std::uint64_t now = pool_cpu_ns(pool);
  const std::uint64_t d = now - t;
  t = now;
  return d;
}

// Objects per chunk of the LOD pass: best_cut is O(n log n) in the share, so
// a few objects a chunk already balance the two threads.
constexpr std::size_t kLodGrain = 4;

// Cancelled: the lists before stay (a valid scene list by definition).
void keep_previous_lists(const SceneIterationInput& input, SceneIterationOutput& output,
                         std::size_t n) {
  output.nodes->assign(input.previous.begin(), input.previous.end());
  output.offsets->assign(input.previous_offsets.begin(), input.previous_offsets.end());
  if (output.offsets->size() != n + 1) output.offsets->assign(n + 1, 0);
  if (output.offsets->back() != output.nodes->size()) {
    output.nodes->clear();
    output.offsets->assign(n + 1, 0);
  }
  output.result.cancelled = true;
}

std::vector<ParamSpec> budget_specs() {
  return {
      {"points", "N: points (splats) for the whole scene, shared by Eq. 1", 1'000'000.0, 0.0, 1e9,
       true},
      {"alpha", "exponent of Eq. 1 (> 1; the paper uses 3)", 3.0, 1.01, 16.0, false},
      {"pet", "pixel error threshold: objects whose screen rectangle is smaller (px^2) get nothing",
       1.0, 0.0, 1e7, false},
      {"culling", "1: hierarchical Z-map occlusion culling, 0: frustum culling only", 1.0, 0.0, 1.0,
       true},
      {"occluders", "size of the active occluder set (Eq. 3 weights, highest first)", 32.0, 0.0,
       4096.0, true},
      {"ct", "compactness threshold CT of the candidate occluders (Eq. 2)", 0.55, 0.0, 1.0, false},
      {"threads", "worker pool size, the stage thread included", 2.0, 1.0, 2.0, true},
  };
}

}  // namespace

BudgetStrategy::BudgetStrategy() : Strategy(budget_specs()) {}
BudgetStrategy::~BudgetStrategy() = default;

void BudgetStrategy::reset(const Hierarchy& /*hierarchy*/) {
  // A single model keeps no state: iterate() is a function of the view.
}

void BudgetStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  // One object, no culling, no sharing: the whole budget is its share. At
  // least the root, since a single model's list must be a cut.
  const auto n = static_cast<std::size_t>(std::max(1.0, param_at(kPoints)));
  many::best_cut(input.hierarchy, input.view, n, *output.nodes, {}, output.wanted);
  output.result.visited = output.nodes->size();
  output.result.converged = true;  // a function of the view and parameters only
}

// A model drawn from its pages (paged_hierarchy.hpp) has read its first
// page when the scene is reset, not its points: the box is fitted to that
// page's leaves (coarse nodes, most of them, each at the centre of the
// points below it) and the splats' box is their spheres' (every splat
// below a node lies in its sphere), so culling stays conservative. It
// occludes nothing: an inner box found among so few samples could cover a
// hole its points have, and an object culled wrongly is a hole in the
// picture.
void BudgetStrategy::paged_points(const Hierarchy& h, std::vector<glm::vec3>& points,
                                  ModelShape& s) {
  s.splat_lo = glm::vec3(INFINITY);
  s.splat_hi = glm::vec3(-INFINITY);
  for_each_resident_leaf(h, [&](NodeId n) {
    points.push_back(h.center(n));
    s.splat_lo = glm::min(s.splat_lo, h.center(n) - glm::vec3(h.radius(n)));
    s.splat_hi = glm::max(s.splat_hi, h.center(n) + glm::vec3(h.radius(n)));
  });
}

// Section 6.1 for one distinct model H (instances share it): its points (a
// paged model's: paged_points), the box fitted to them, Eq. 2, and a box
// inside. POINTS: scratch.
BudgetStrategy::ModelShape BudgetStrategy::model_shape(const Hierarchy& h, bool paged,
                                                       std::vector<glm::vec3>& points) {
  ModelShape s;
  s.hierarchy = &h;
  points.clear();
  if (paged) {
    paged_points(h, points, s);
  } else {
    float radius = 0.0f;
    for (NodeId n = 0; n < h.node_count(); ++n) {
      if (h.is_leaf(n)) {
        points.push_back(h.center(n));
        radius = std::max(radius, h.radius(n));
      }
    }
    // The splats' box (centres grown by the largest splat radius): what the
    // renderer can cover, so what frustum culling and the HZM test must take.
    s.splat_lo = h.bounds_min() - glm::vec3(radius);
    s.splat_hi = h.bounds_max() + glm::vec3(radius);
  }
  // The principal axes are arbitrary for a model whose covariance is
  // nearly isotropic (a cube): the model's own axis-aligned box is the
  // other candidate, the smaller volume wins.
  const culling::Obb fitted = culling::fit_obb(points);
  const glm::vec3 lo = h.bounds_min(), hi = h.bounds_max();
  const culling::Obb aligned{0.5f * (lo + hi), glm::mat3(1.0f), 0.5f * (hi - lo)};
  const auto volume = [](const culling::Obb& b) { return b.half.x * b.half.y * b.half.z; };
  s.box = volume(fitted) < 0.98f * volume(aligned) ? fitted : aligned;
  s.compactness = culling::compactness(points, s.box);
  if (paged) return s;  // occludes nothing (paged_points)
  // A grid with about 16 points per surface cell (the six faces of n x n
  // cells hold 6 n^2): random sampling then leaves no cell of a closed
  // surface empty (e^-16), and an empty cell would read as a hole.
  const int cells = std::clamp(
      static_cast<int>(std::sqrt(static_cast<double>(points.size()) / (6.0 * 16.0))), 3, 32);
  s.inner = culling::inner_box(points, s.box, cells);
  // A surface open on one face (a building without a floor: the flood
  // from outside leaks in through it): closed by that face's plane, the
  // box found (which may reach the plane) is inside the solid for every
  // eye on the inner side of the plane (a ray from there cannot pass
  // through the open face into the box without crossing the plane twice),
  // so the object occludes exactly while the eye is there (iterate_scene).
  for (int face = 0; !s.inner && face < 6 && !points.empty(); ++face) {
    s.inner = culling::inner_box(points, s.box, cells, face);
    if (s.inner) s.open_face = face;
  }
  return s;
}

void BudgetStrategy::reset_scene(const StageScene& scene) {
  const std::span<const SceneObject> objects = scene.objects;
  // Section 6.1 per distinct model (instances share it): the points are the
  // hierarchy's leaves, the box fitted to them, Eq. 2, and a box inside.
  std::uint32_t models = 0;
  for (const SceneObject& o : objects) models = std::max(models, o.model + 1);
  std::vector<ModelShape> shapes(models);
  std::vector<glm::vec3> points;
  for (const SceneObject& o : objects) {
    ModelShape& s = shapes[o.model];
    if (s.hierarchy != nullptr) continue;
    s = model_shape(*scene.models[o.model], scene.paged_model(o.model) != nullptr, points);
  }
  std::vector<culling::ObjectBounds> made(objects.size());
  open_.clear();
  open_planes_.clear();
  open_inside_.clear();
  hierarchies_.resize(objects.size());
  worlds_.resize(objects.size());
  points_.resize(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const SceneObject& o = objects[i];
    const ModelShape& s = shapes[o.model];
    culling::ObjectBounds& x = made[i];
    x.box = culling::transformed(s.box, o.world);
    // The fitted box holds the splat centres; the splats' box moved holds
    // every pixel a splat can cover.
    x.bounds = culling::bounds_of(x.box);
    const culling::Obb aabb{0.5f * (s.splat_lo + s.splat_hi), glm::mat3(1.0f),
                            0.5f * (s.splat_hi - s.splat_lo)};
    const culling::Box b = culling::bounds_of(culling::transformed(aabb, o.world));
    x.bounds.lo = glm::min(x.bounds.lo, b.lo);
    x.bounds.hi = glm::max(x.bounds.hi, b.hi);
    x.has_inner = s.inner.has_value();
    if (x.has_inner) x.inner = culling::transformed(*s.inner, o.world);
    x.points = scene.hierarchy(i).leaf_count();
    points_[i] = x.points;
    x.compactness = s.compactness;
    if (s.open_face >= 0) {
      // The eye is on the face's inner side when
      //   sign * dot(world_inverse * eye - centre, axis) < half,
      // a plane in world space: (p, d) with dot(p, eye) + d < 0, in double
      // (one dot product a frame instead of a matrix product per object).
      const int k = s.open_face / 2;
      const double sign = s.open_face % 2 ? 1.0 : -1.0;
      const glm::dvec4 q =
          glm::transpose(glm::dmat4(o.world_inverse)) * glm::dvec4(glm::dvec3(s.box.axes[k]), 0.0);
      const double offset = q.w - glm::dot(glm::dvec3(s.box.center), glm::dvec3(s.box.axes[k]));
      open_.push_back(static_cast<std::uint32_t>(i));
      open_inside_.push_back(x.has_inner ? 1 : 0);
      open_planes_.push_back(
          glm::dvec4(sign * glm::dvec3(q), sign * offset - static_cast<double>(s.box.half[k])));
    }
    hierarchies_[i] = &scene.hierarchy(i);
    worlds_[i] = o.world;
  }
  shapes_.swap(shapes);
  objects_.swap(made);
  cuts_.assign(objects_.size(), {});
  wanted_.assign(objects_.size(), {});
  culler_.reset();  // preprocessed again for these objects
}

void BudgetStrategy::ensure_pool() {
  const auto threads = static_cast<unsigned>(param_at(kThreads));
  if (!pool_ || pool_->threads() != threads) {
    pool_.reset();  // its workers joined before the new ones start
    pool_ = std::make_unique<WorkerPool>(threads);
  }
}

void BudgetStrategy::ensure_culler() {
  culling::HzmParams p;
  p.active = static_cast<std::size_t>(param_at(kOccluders));
  p.compactness_threshold = static_cast<float>(param_at(kCompactness));
  if (!culler_ || culler_params_.active != p.active ||
      culler_params_.compactness_threshold != p.compactness_threshold) {
    culler_ = std::make_unique<culling::HzmCuller>(p);
    culler_->preprocess(objects_);
    culler_params_ = p;
  }
}

// The clocks of one scene iteration's phases: each lap is the wall and CPU
// time since the previous lap (or since the clock was made).
struct BudgetStrategy::PhaseClock {
  explicit PhaseClock(const WorkerPool& p) : pool(p), t(Clock::now()), cpu(pool_cpu_ns(p)) {}
  void lap(std::uint64_t& wall_ns, std::uint64_t& cpu_ns) {
    wall_ns = ns_since(t);
    cpu_ns = cpu_since(pool, cpu);
  }
  const WorkerPool& pool;
  Clock::time_point t;
  std::uint64_t cpu;
};

bool BudgetStrategy::update_open_faces(const ViewSnapshot& view) {
  // Objects open on one face occlude only while the eye is on its inner side.
  const glm::dvec3 eye(view.derived.eye);
  bool moved = false;
  for (std::size_t j = 0; j < open_.size(); ++j) {
    const glm::dvec4& p = open_planes_[j];
    const std::uint8_t inside = glm::dot(glm::dvec3(p), eye) + p.w < 0.0 ? 1 : 0;
    // The dense copy of has_inner: the SceneObjects (156 bytes each) are
    // touched only where it changes.
    if (open_inside_[j] != inside) {
      open_inside_[j] = inside;
      objects_[open_[j]].has_inner = inside != 0;
      moved = true;
    }
  }
  return moved;
}

void BudgetStrategy::cull(const ViewSnapshot& view, WorkerPool* pool, PhaseClock& clock,
                          BudgetCounters& c) {
  const std::size_t n = objects_.size();
  culling::HzmCuller& culler = *culler_;
  const bool culling = param_at(kCulling) != 0.0;
  culler.project(objects_, view, pool);
  clock.lap(c.project_ns, c.project_cpu_ns);
  if (!culling) {
    visible_.resize(n);
    const auto rects = culler.rects();
    for (std::size_t i = 0; i < n; ++i) {
      visible_[i] = rects[i].in_frustum ? 1 : 0;
      c.frustum_culled += rects[i].in_frustum ? 0 : 1;
      c.visible += visible_[i];
    }
    return;
  }
  culler.select_occluders(objects_, view, pool);
  clock.lap(c.select_ns, c.select_cpu_ns);
  culler.build_hzm(objects_, view, pool);
  clock.lap(c.hzm_ns, c.hzm_cpu_ns);
  culler.test(objects_, pool);
  clock.lap(c.test_ns, c.test_cpu_ns);
  visible_.assign(culler.visible().begin(), culler.visible().end());
  c.occluders = culler.active().size();
  // The counts from the states (a byte an object; Outside is exactly the
  // frustum culled), not from the rectangles (24 bytes an object).
  const auto states = culler.states();
  for (std::size_t i = 0; i < n; ++i) {
    c.occlusion_culled += states[i] == culling::ObjectState::Occluded ? 1 : 0;
    c.frustum_culled += states[i] == culling::ObjectState::Outside ? 1 : 0;
    c.visible += visible_[i];
  }
}

void BudgetStrategy::share_budget(WorkerPool* pool, BudgetCounters& c) {
  // Eq. 1 over the visible set: a culled object's area is 0, its share goes
  // to the others.
  many::BudgetParams bp;
  bp.total = static_cast<std::uint64_t>(param_at(kPoints));
  bp.alpha = param_at(kAlpha);
  bp.pet = param_at(kPet);
  many::budget_items(points_, culler_->rects(), visible_, items_, pool);
  const many::BudgetStats bs = many::allocate_budget(items_, bp, shares_, pool);
  c.below_pet = bs.below_pet;
  c.receiving = bs.receiving;
  c.shares = bs.total;
}

std::size_t BudgetStrategy::select_cuts(const ViewSnapshot& view, WorkerPool& pool,
                                        SceneIterationOutput& output) {
  const std::size_t n = objects_.size();
  // Each share a cut of its object's hierarchy, objects in parallel (each
  // writes only its own list).
  pool.run(n, kLodGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) {
      if (shares_[i] == 0) {
        cuts_[i].clear();
        continue;
      }
      const ViewSnapshot v = culling::object_view(view, worlds_[i]);
      // Into the object's list of the last iteration: its storage is reused.
      wanted_[i].clear();
      many::best_cut(*hierarchies_[i], v, shares_[i], cuts_[i], {},
                     output.wanted != nullptr ? &wanted_[i] : nullptr);
    }
  });
  if (output.wanted != nullptr) {
    for (std::size_t i = 0; i < n; ++i)
      if (shares_[i] != 0)
        for (const NodeId w : wanted_[i])
          output.wanted->push_back({static_cast<std::uint32_t>(i), w});
  }
  // The lists back to back, object i's at offsets[i] .. offsets[i + 1].
  output.offsets->resize(n + 1);
  (*output.offsets)[0] = 0;
  std::size_t total = 0;
  for (std::size_t i = 0; i < n; ++i) {
    total += cuts_[i].size();
    (*output.offsets)[i + 1] = static_cast<std::uint32_t>(total);
  }
  output.nodes->reserve(total);
  for (std::size_t i = 0; i < n; ++i) {
    output.nodes->insert(output.nodes->end(), cuts_[i].begin(), cuts_[i].end());
  }
  return total;
}

void BudgetStrategy::iterate_scene(const SceneIterationInput& input, SceneIterationOutput& output) {
  const std::size_t n = objects_.size();
  if (input.scene.objects.size() != n) {
    throw std::logic_error("budget: " + std::to_string(input.scene.objects.size()) +
                           " objects, reset_scene saw " + std::to_string(n));
  }
  ensure_pool();
  WorkerPool* pool = pool_.get();
  BudgetCounters c;
  c.objects = n;
  // The culler needs a perspective frustum (this throws otherwise: the
  // stage names it as this strategy's error).
  const ViewSnapshot& view = input.view;
  culling::require_perspective_frustum(view);
  // From here on everything but best_cut is "select + cull" (the open-face
  // check and a preprocess it needs count as projection).
  PhaseClock clock(*pool);
  const bool moved = update_open_faces(view);
  const bool made_culler = !culler_;
  ensure_culler();
  if (moved && !made_culler) culler_->preprocess(objects_);

  cull(view, pool, clock, c);
  if (input.cancelled()) return keep_previous_lists(input, output, n);
  share_budget(pool, c);
  clock.lap(c.budget_ns, c.budget_cpu_ns);
  if (input.cancelled()) return keep_previous_lists(input, output, n);
  c.selected = select_cuts(view, *pool, output);
  clock.lap(c.lod_ns, c.lod_cpu_ns);

  output.result.visited = n;
  output.result.culled = c.frustum_culled + c.occlusion_culled;
  output.result.too_small = c.below_pet;
  output.result.converged = true;  // a function of the view and parameters only
  last_ = c;
  publish(c, output.result.counters);
}

void BudgetStrategy::publish(const BudgetCounters& c, Counters& out) {
  // The objects by what became of them, the occluder set, Eq. 1's shares and
  // the nodes selected, and the wall time of each phase of the frame
  // (docs/many-objects.md).
  out.set("budget_visible", double(c.visible), "objects");
  out.set("budget_frustum_culled", double(c.frustum_culled), "objects");
  out.set("budget_occlusion_culled", double(c.occlusion_culled), "objects");
  out.set("budget_below_pet", double(c.below_pet), "objects");
  out.set("budget_receiving", double(c.receiving), "objects");
  out.set("budget_occluders", double(c.occluders), "objects");
  out.set("budget_shares", double(c.shares), "points");
  out.set("budget_selected", double(c.selected), "nodes");
  out.set("budget_project_ms", double(c.project_ns) * 1e-6, "ms");
  out.set("budget_select_ms", double(c.select_ns) * 1e-6, "ms");
  out.set("budget_hzm_ms", double(c.hzm_ns) * 1e-6, "ms");
  out.set("budget_test_ms", double(c.test_ns) * 1e-6, "ms");
  out.set("budget_eq1_ms", double(c.budget_ns) * 1e-6, "ms");
  out.set("budget_lod_ms", double(c.lod_ns) * 1e-6, "ms");
}

}  // namespace treecut::strategies
