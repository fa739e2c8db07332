// Loading a scene (scene.hpp): the distinct models once each, several at a
// time, then the objects' world bounds. Instances share one Hierarchy: the
// same file (device and inode, so hard links, symbolic links and two spellings
// of one path count as one) or the same generated kind, seed and point count.
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat3x3.hpp>
#include <limits>
#include <map>
#include <mutex>
#include <thread>
#include <tuple>

#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/parallel.hpp"
#include "treecut/scene.hpp"

namespace treecut {

namespace {

// The largest factor by which A stretches a vector (its spectral norm): the
// square root of the largest eigenvalue of A^T A, in closed form for a
// symmetric 3x3 (the trigonometric solution). A bounding sphere's radius
// scales by it under any invertible linear map, sheared or not.
double max_stretch(const glm::dmat3& a) {
  const glm::dmat3 b = glm::transpose(a) * a;
  const double p1 = b[0][1] * b[0][1] + b[0][2] * b[0][2] + b[1][2] * b[1][2];
  double top = 0.0;
  if (p1 == 0.0) {
    top = std::max({b[0][0], b[1][1], b[2][2]});
  } else {
    const double q = (b[0][0] + b[1][1] + b[2][2]) / 3.0;
    const double p2 = (b[0][0] - q) * (b[0][0] - q) + (b[1][1] - q) * (b[1][1] - q) +
                      (b[2][2] - q) * (b[2][2] - q) + 2.0 * p1;
    const double p = std::sqrt(p2 / 6.0);
    const glm::dmat3 c = (1.0 / p) * (b - q * glm::dmat3(1.0));
    const double r = std::clamp(glm::determinant(c) / 2.0, -1.0, 1.0);
    top = q + 2.0 * p * std::cos(std::acos(r) / 3.0);
  }
  // A hair more than exact: the radius must bound, rounding included.
  return std::sqrt(std::max(top, 0.0)) * (1.0 + 1e-9);
}

// Rounded outward to a float; past the float range an infinity (a plain
// cast of such a double is undefined behaviour).
float down(double v) {
  if (!(v >= -double(std::numeric_limits<float>::max()))) return -INFINITY;
  if (v > double(std::numeric_limits<float>::max())) return std::numeric_limits<float>::max();
  const auto f = static_cast<float>(v);
  return double(f) > v ? std::nextafter(f, -INFINITY) : f;
}
float up(double v) {
  if (!(v <= double(std::numeric_limits<float>::max()))) return INFINITY;
  if (v < -double(std::numeric_limits<float>::max())) return -std::numeric_limits<float>::max();
  const auto f = static_cast<float>(v);
  return double(f) < v ? std::nextafter(f, INFINITY) : f;
}

// Model-space box around every splat: each leaf is a disc of its radius r
// about its point, perpendicular to its normal n, so along axis k it reaches
// r * sqrt(1 - n_k^2) from the point (the normals are snorm16: 0.01 more
// covers their rounding near n_k = 1).
void splat_box(const Hierarchy& h, glm::vec3& lo, glm::vec3& hi) {
  lo = glm::vec3(INFINITY);
  hi = glm::vec3(-INFINITY);
  const auto& a = h.arrays();
  for (std::uint32_t n = 0; n < h.node_count(); ++n) {
    if (a.child_count[n] != 0) continue;
    const glm::vec3 p(a.center_radius[n]), nrm = h.normal(n);
    const float r = a.center_radius[n].w;
    glm::vec3 reach;
    for (int k = 0; k < 3; ++k)
      reach[k] = r * std::min(1.0f, std::sqrt(std::max(0.0f, 1.0f - nrm[k] * nrm[k])) + 0.01f);
    lo = glm::min(lo, p - reach);
    hi = glm::max(hi, p + reach);
  }
}

// The same box for a model drawn from its pages, from what is resident (its
// first page): each leaf's sphere, since a leaf there is most often a node
// whose children are not read yet, and every splat below a node lies in
// its sphere. Looser than a whole model's box, never smaller; the nodes
// that are not resident read as zeros and are not visited.
void paged_splat_box(const Hierarchy& h, glm::vec3& lo, glm::vec3& hi) {
  lo = glm::vec3(INFINITY);
  hi = glm::vec3(-INFINITY);
  for_each_resident_leaf(h, [&](NodeId n) {
    lo = glm::min(lo, h.center(n) - glm::vec3(h.radius(n)));
    hi = glm::max(hi, h.center(n) + glm::vec3(h.radius(n)));
  });
}

// Each cache's part of a paging budget TOTAL (0: none), in proportion to
// its file's size among the caches a scene draws from their pages; a cache
// by URL (its size unknown until it opens) weighs the files' average.
std::vector<std::uint64_t> paging_shares(const std::vector<std::filesystem::path>& caches,
                                         std::uint64_t total) {
  std::vector<double> weight(caches.size(), 0.0);
  std::vector<std::uint64_t> share(caches.size(), 0);
  double files = 0.0, file_bytes = 0.0;
  for (std::size_t i = 0; i < caches.size(); ++i) {
    if (caches[i].empty() || is_cache_url(caches[i].string())) continue;
    std::error_code ec;
    const std::uintmax_t bytes = std::filesystem::file_size(caches[i], ec);
    weight[i] = ec ? 0.0 : double(bytes);
    files += 1.0, file_bytes += weight[i];
  }
  const double average = file_bytes > 0.0 ? file_bytes / files : 1.0;
  double all = 0.0;
  for (std::size_t i = 0; i < caches.size(); ++i) {
    if (caches[i].empty()) continue;
    if (is_cache_url(caches[i].string())) weight[i] = average;
    all += weight[i];
  }
  if (total == 0 || all <= 0.0) return share;
  for (std::size_t i = 0; i < caches.size(); ++i)
    share[i] = static_cast<std::uint64_t>(double(total) * weight[i] / all);
  return share;
}

// A copy of EXAMPLE (InputError or not) with MESSAGE.
[[noreturn]] void rethrow_with(std::exception_ptr example, const std::string& prefix) {
  try {
    std::rethrow_exception(example);
  } catch (const InputError& e) {
    throw InputError(prefix + e.what());
  } catch (const FileChangedError& e) {
    throw FileChangedError(prefix + e.what());
  } catch (const std::exception& e) {
    throw std::runtime_error(prefix + e.what());
  }
}

// 1. Distinct models, in order of first use; declarations no object uses
//    are not loaded. Fills model_of_decl (UINT32_MAX: unused) and returns
//    the declaration of each model.
std::vector<std::uint32_t> distinct_models(const SceneDescription& d, const Scene& scene,
                                           std::vector<std::uint32_t>& model_of_decl) {
  std::map<std::pair<dev_t, ino_t>, std::uint32_t> by_file;
  std::map<std::string, std::uint32_t> by_url;
  std::map<std::tuple<std::string, std::uint64_t, std::uint64_t>, std::uint32_t> by_kind;
  model_of_decl.assign(d.models.size(), UINT32_MAX);
  std::vector<std::uint32_t> decl_of_model;
  for (const auto& o : d.objects) {
    std::uint32_t& m = model_of_decl[o.model];
    if (m != UINT32_MAX) continue;
    const SceneModelDecl& decl = d.models[o.model];
    const auto next = static_cast<std::uint32_t>(decl_of_model.size());
    if (decl.source.type == SceneModelSource::Type::File &&
        is_cache_url(decl.source.file.string())) {
      m = by_url.try_emplace(decl.source.file.string(), next).first->second;
    } else if (decl.source.type == SceneModelSource::Type::File) {
      struct stat st {};
      if (::stat(decl.source.file.c_str(), &st) != 0)
        throw InputError(quoted_name(scene.files[decl.file]) + ":" + std::to_string(decl.line) +
                         ": model '" + decl.name +
                         "': " + system_error_text(decl.source.file, errno));
      m = by_file.try_emplace({st.st_dev, st.st_ino}, next).first->second;
    } else {
      m = by_kind.try_emplace({decl.source.kind, decl.source.seed, decl.source.points}, next)
              .first->second;
    }
    if (m == next) decl_of_model.push_back(o.model);
  }
  return decl_of_model;
}

// 2. Load them, several at a time (each load is itself parallel inside: a
//    few large models keep the cores busy either way, many small ones would
//    not), into scene.models; the first failure (in model order) is thrown
//    naming its declaration.
void load_models(const SceneDescription& d, const std::vector<std::uint32_t>& decl_of_model,
                 const SceneLoadOptions& options, Scene& scene) {
  const std::size_t count = decl_of_model.size();
  std::vector<std::shared_ptr<const Hierarchy>> loaded(count);
  std::vector<std::shared_ptr<PagedHierarchy>> paged(count);
  // The caches drawn from their pages, and their parts of the budgets.
  std::vector<std::filesystem::path> caches(count);
  for (std::size_t i = 0; i < count; ++i) {
    const SceneModelDecl& decl = d.models[decl_of_model[i]];
    if (decl.source.type != SceneModelSource::Type::File) continue;
    const bool url = is_cache_url(decl.source.file.string());
    if (url && !options.paging)
      throw InputError(quoted_name(scene.files[decl.file]) + ":" + std::to_string(decl.line) +
                       ": model '" + decl.name +
                       "': a cache by URL is drawn from its pages, within a memory budget: "
                       "give one (--memory)");
    if (options.paging && (url || looks_like_cache(decl.source.file))) caches[i] = decl.source.file;
  }
  const std::vector<std::uint64_t> memory_share =
      paging_shares(caches, options.paging ? options.paging->memory_bytes : 0);
  const std::vector<std::uint64_t> node_share =
      paging_shares(caches, options.paging ? options.paging->node_limit : 0);
  // char, not bool: the workers write neighbouring elements at once.
  std::vector<char> cached(count, 0);
  std::vector<std::exception_ptr> errors(count);
  std::mutex warn_mutex;
  OpenOptions open = options.open;
  open.progress = nullptr;
  open.build.progress = nullptr;
  if (options.open.warn) {
    open.warn = [&warn_mutex, &options](const std::string& w) {
      const std::lock_guard lock(warn_mutex);
      options.open.warn(w);
    };
  }
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i = next++; i < count; i = next++) {
      const SceneModelDecl& decl = d.models[decl_of_model[i]];
      try {
        if (!caches[i].empty()) {
          PagingOptions paging = *options.paging;
          // Shares of the budgets (0 is none: no share of it either).
          paging.memory_bytes =
              paging.memory_bytes != 0 ? std::max<std::uint64_t>(memory_share[i], 1) : 0;
          paging.node_limit =
              paging.node_limit != 0 ? std::max<std::uint64_t>(node_share[i], 1) : 0;
          paged[i] = PagedHierarchy::open(caches[i], paging);
          loaded[i] = std::shared_ptr<const Hierarchy>(paged[i], &paged[i]->hierarchy());
          cached[i] = 1;
        } else if (decl.source.type == SceneModelSource::Type::File) {
          OpenedModel opened = open_model(decl.source.file, open);
          cached[i] = opened.from_cache ? 1 : 0;
          loaded[i] = std::make_shared<const Hierarchy>(std::move(opened.hierarchy));
        } else {
          loaded[i] = std::make_shared<const Hierarchy>(build_from_points(
              options.parse.generator.make(decl.source.kind, decl.source.points, decl.source.seed),
              open.attributes, open.build));
        }
      } catch (...) {
        errors[i] = std::current_exception();
      }
    }
  };
  const auto t0 = std::chrono::steady_clock::now();
  {
    const unsigned workers =
        static_cast<unsigned>(std::min<std::size_t>(worker_count(options.threads), count));
    std::vector<std::jthread> pool;
    for (unsigned w = 1; w < workers; ++w) pool.emplace_back(work);
    work();
  }
  scene.load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (std::size_t i = 0; i < count; ++i) {
    if (!errors[i]) continue;
    const SceneModelDecl& decl = d.models[decl_of_model[i]];
    rethrow_with(errors[i], quoted_name(scene.files[decl.file]) + ":" + std::to_string(decl.line) +
                                ": model '" + decl.name + "': ");
  }
  scene.models.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const SceneModelDecl& decl = d.models[decl_of_model[i]];
    SceneModel& m = scene.models[i];
    m.name = decl.name;
    m.source = decl.source;
    m.declared_at = quoted_name(scene.files[decl.file]) + ":" + std::to_string(decl.line);
    m.hierarchy = std::move(loaded[i]);
    m.from_cache = cached[i] != 0;
    m.paged = std::move(paged[i]);
    if (m.paged)
      paged_splat_box(*m.hierarchy, m.box_min, m.box_max);
    else
      splat_box(*m.hierarchy, m.box_min, m.box_max);
  }
}

// The object's world bounds: its model's splat box through the world
// matrix, rounded outwards to floats, and the smaller of two spheres (the
// model's root sphere moved, the box's). False when they do not fit in floats.
bool place_object(const SceneModel& m, SceneObject& o) {
  const glm::dmat4 w(o.world);
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 corner(c & 1 ? m.box_max.x : m.box_min.x, c & 2 ? m.box_max.y : m.box_min.y,
                            c & 4 ? m.box_max.z : m.box_min.z);
    const glm::dvec3 p(w * glm::dvec4(corner, 1.0));
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  o.aabb_min = {down(lo.x), down(lo.y), down(lo.z)};
  o.aabb_max = {up(hi.x), up(hi.y), up(hi.z)};
  bool finite = true;
  for (int k = 0; k < 3; ++k)
    finite = finite && std::isfinite(o.aabb_min[k]) && std::isfinite(o.aabb_max[k]);
  if (finite) {
    const glm::dvec3 root = glm::dvec3(m.hierarchy->center(0));
    const glm::dvec3 c1(w * glm::dvec4(root, 1.0));
    const double r1 = double(m.hierarchy->radius(0)) * max_stretch(glm::dmat3(w));
    const glm::dvec3 c2 = 0.5 * (lo + hi);
    const double r2 = 0.5 * glm::length(hi - lo);
    // The root sphere is inside the AABB's range: its centre fits a float.
    const bool first = r1 <= r2;
    const glm::dvec3 c = first ? c1 : c2;
    o.sphere = glm::vec4(glm::vec3(c), up((first ? r1 : r2) * (1.0 + 1e-6)));
    finite = std::isfinite(o.sphere.w);
  }
  return finite;
}

// 3. The objects, their world bounds (the first object whose bounds do not
//    fit in floats is an error), the models' instance counts and the
//    scene's bounds.
void place_objects(const SceneDescription& d, const std::vector<std::uint32_t>& model_of_decl,
                   Scene& scene) {
  // Map coordinates: every georeferenced model relative to the first one's
  // origin, the difference taken in double (metres apart, not 5e6 m).
  for (const SceneModel& m : scene.models) {
    if (m.hierarchy->frame().origin != glm::dvec3(0.0)) {
      scene.origin = m.hierarchy->frame().origin;
      break;
    }
  }
  std::vector<glm::vec3> shift(scene.models.size(), glm::vec3(0.0f));
  for (std::size_t i = 0; i < scene.models.size(); ++i) {
    const glm::dvec3 o = scene.models[i].hierarchy->frame().origin;
    if (o != glm::dvec3(0.0)) shift[i] = glm::vec3(o - scene.origin);
  }
  scene.objects.resize(d.objects.size());
  std::atomic<bool> failed{false};
  std::atomic<std::size_t> first_bad{SIZE_MAX};
  parallel_for(d.objects.size(), [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const SceneObject& od = d.objects[i];
      SceneObject& o = scene.objects[i];
      o.model = model_of_decl[od.model];
      o.world = od.world;
      o.world_inverse = od.world_inverse;
      if (const glm::vec3 t = shift[o.model]; t != glm::vec3(0.0f)) {
        // After the object's transform: it turns and scales the model about
        // the model's own origin, then the model moves to its map position.
        o.world = glm::translate(glm::mat4(1.0f), t) * o.world;
        o.world_inverse = o.world_inverse * glm::translate(glm::mat4(1.0f), -t);
      }
      o.file = od.file;
      o.line = od.line;
      if (!place_object(scene.models[o.model], o)) {
        failed = true;
        std::size_t cur = first_bad.load();
        while (i < cur && !first_bad.compare_exchange_weak(cur, i)) {
        }
      }
    }
  });
  if (failed) {
    const SceneObject& o = scene.objects[first_bad.load()];
    throw InputError(scene.where(o) + ": the object's world bounds do not fit in floats");
  }
  for (auto& o : scene.objects) ++scene.models[o.model].instances;
  scene.bounds_min = glm::vec3(INFINITY);
  scene.bounds_max = glm::vec3(-INFINITY);
  for (const auto& o : scene.objects) {
    scene.bounds_min = glm::min(scene.bounds_min, o.aabb_min);
    scene.bounds_max = glm::max(scene.bounds_max, o.aabb_max);
  }
}

// 4. Map coordinates: the world is floats from its zero, so a georeferenced
//    model reaching 32,768 units from it or more is rounded by a millimetre
//    or more there (docs/files.md, map coordinates). Said once per model.
void warn_far_models(const Scene& scene, const WarningSink& warn) {
  if (!warn) return;
  std::vector<float> reach(scene.models.size(), 0.0f);
  for (const SceneObject& o : scene.objects) {
    if (scene.models[o.model].hierarchy->frame().origin == glm::dvec3(0.0)) continue;
    const glm::vec3 far = glm::max(glm::abs(o.aabb_min), glm::abs(o.aabb_max));
    reach[o.model] = std::max({reach[o.model], far.x, far.y, far.z});
  }
  for (std::size_t m = 0; m < scene.models.size(); ++m) {
    if (reach[m] < 32768.0f) continue;
    const float spacing = std::nextafter(reach[m], INFINITY) - reach[m];
    char line[240];
    std::snprintf(line, sizeof line,
                  ": model %s reaches %.0f units from the scene's origin (its first "
                  "georeferenced model's): as floats the spacing there is %.3g units (rounding "
                  "under 1/1000 within 32768 units)",
                  scene.models[m].name.c_str(), double(reach[m]), double(spacing));
    warn(scene.models[m].declared_at + line);
  }
}

}  // namespace

std::uint64_t Scene::instanced_points() const {
  std::uint64_t n = 0;
  for (const auto& o : objects) n += models[o.model].hierarchy->leaf_count();
  return n;
}

std::uint64_t Scene::distinct_points() const {
  std::uint64_t n = 0;
  for (const auto& m : models) n += m.hierarchy->leaf_count();
  return n;
}

std::string Scene::where(const SceneObject& object) const {
  return quoted_name(files[object.file]) + ":" + std::to_string(object.line);
}

double SceneMemory::per_object_bytes() const {
  return objects ? static_cast<double>(hierarchy_bytes + object_bytes) / double(objects) : 0.0;
}

SceneMemory scene_memory(const Scene& scene) {
  SceneMemory m;
  m.objects = scene.objects.size();
  // A model drawn from its pages holds what is resident.
  const auto held = [](const SceneModel& model) {
    return model.paged ? model.paged->stats().resident_bytes : model.hierarchy->memory_bytes();
  };
  for (const auto& model : scene.models) m.hierarchy_bytes += held(model);
  m.object_bytes =
      scene.objects.size() * sizeof(SceneObject) + scene.models.size() * sizeof(SceneModel);
  for (const auto& o : scene.objects) m.unshared_bytes += held(scene.models[o.model]);
  return m;
}

Scene load_scene(const std::filesystem::path& file, const SceneLoadOptions& options) {
  SceneDescription d = parse_scene_file(file, options.parse);
  Scene scene;
  scene.files = std::move(d.files);
  std::vector<std::uint32_t> model_of_decl;
  const std::vector<std::uint32_t> decl_of_model = distinct_models(d, scene, model_of_decl);
  load_models(d, decl_of_model, options, scene);
  place_objects(d, model_of_decl, scene);
  warn_far_models(scene, options.open.warn);
  return scene;
}

}  // namespace treecut
