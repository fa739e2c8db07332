// Per-point attributes: normals, splat radii, curvature.
//
// With faces (a mesh): area-weighted face normals, a splat radius that covers
// every incident triangle, and curvature from the covariance of the 1-ring.
// Without faces (a point cloud): PCA over the k nearest neighbours (Hoppe et
// al. 1992) oriented away from the centroid (a survey, whose format says z is
// up, facing up where it is not a wall), a radius from the local density
// and the surface variation of Pauly et al. 2002.
#include "treecut/attributes.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <vector>

#include "knn_grid.hpp"
#include "symmetric3.hpp"
#include "treecut/parallel.hpp"

namespace treecut {

namespace {

using detail::Sym3;

// Radius that makes the discs of a triangle's corners cover the triangle: the
// circumradius, or half the longest edge when the triangle is obtuse (its
// circumcenter lies outside, and the edge midpoint is the farthest point).
float covering_radius(glm::vec3 a, glm::vec3 b, glm::vec3 c) {
  const float ab = glm::distance(a, b), bc = glm::distance(b, c), ca = glm::distance(c, a);
  const float longest = std::max({ab, bc, ca});
  const float area2 = glm::length(glm::cross(b - a, c - a));  // twice the area
  const float sq = ab * ab + bc * bc + ca * ca;
  const float l2 = longest * longest;
  if (area2 <= 0.0f || 2.0f * l2 >= sq) return 0.5f * longest;  // obtuse or degenerate
  return std::min(ab * bc * ca / (2.0f * area2), longest);
}

float median_positive(const std::vector<float>& v) {
  std::vector<float> pos;
  pos.reserve(v.size());
  for (float x : v)
    if (x > 0.0f && std::isfinite(x)) pos.push_back(x);
  if (pos.empty()) return 0.0f;
  auto mid = pos.begin() + static_cast<std::ptrdiff_t>(pos.size() / 2);
  std::nth_element(pos.begin(), mid, pos.end());
  return *mid;
}

void normalize_normals(std::vector<glm::vec3>& normals) {
  for (auto& n : normals) {
    const float len = glm::length(n);
    n = len > 1e-20f && std::isfinite(len) ? n / len : glm::vec3(0.0f);
  }
}

// Covariance of a neighbourhood given by offsets d from the point itself:
// E[dd^T] - E[d]E[d]^T (the point counts as one offset of zero).
struct Moments {
  Sym3 outer;
  glm::vec3 sum{0.0f};
  std::uint32_t count = 1;
  void add(glm::vec3 d) {
    outer.add(d);
    sum += d;
    ++count;
  }
  [[nodiscard]] Sym3 covariance() const {
    const float inv = 1.0f / static_cast<float>(count);
    const glm::vec3 m = sum * inv;
    Sym3 c = outer;
    c.xx = c.xx * inv - m.x * m.x, c.xy = c.xy * inv - m.x * m.y, c.xz = c.xz * inv - m.x * m.z;
    c.yy = c.yy * inv - m.y * m.y, c.yz = c.yz * inv - m.y * m.z, c.zz = c.zz * inv - m.z * m.z;
    return c;
  }
};

void fill_missing_radii(std::vector<float>& radii) {
  const bool complete =
      std::all_of(radii.begin(), radii.end(), [](float r) { return r > 0.0f && std::isfinite(r); });
  if (complete) return;
  const float fallback = median_positive(radii);
  for (float& r : radii)
    if (!(r > 0.0f) || !std::isfinite(r)) r = fallback > 0.0f ? fallback : 1.0f;
}

// Isolated points (sparse vegetation, stray returns) have far neighbours, so
// the density rule gives them discs many times the model's typical size:
// 40-pixel blobs where the scan has a leaf (issue 30). A radius from the
// neighbours is held to kSparseRadiusCap times the model's median; the
// scan stays as sparse as it is there, drawn as points, not blobs.
constexpr float kSparseRadiusCap = 4.0f;

void cap_sparse_radii(std::vector<float>& radii) {
  const float cap = kSparseRadiusCap * median_positive(radii);
  if (!(cap > 0.0f)) return;
  for (float& r : radii) r = std::min(r, cap);
}

// Every thread owns a contiguous range of vertices and scans all faces,
// accumulating only into its own vertices: no write conflicts, no incidence
// table, and each vertex sums its faces in ascending order whatever the
// thread count, so the result is deterministic.
void from_faces(PointSet& ps, bool want_normals, bool want_radii, bool want_curvature) {
  const std::size_t n = ps.size();
  struct Accumulator {
    glm::vec3 normal{0.0f};  // sum of face normals * 2 * area: area weighting
    float radius = 0.0f;
    Moments ring;  // the other corners of the incident faces
  };
  std::vector<Accumulator> acc(n);
  const unsigned threads = worker_count();
  parallel_for(
      threads,
      [&](std::size_t tb, std::size_t te) {
        for (std::size_t t = tb; t < te; ++t) {
          const std::uint32_t lo = static_cast<std::uint32_t>(n * t / threads);
          const std::uint32_t hi = static_cast<std::uint32_t>(n * (t + 1) / threads);
          auto own = [lo, hi](std::uint32_t v) { return v >= lo && v < hi; };
          for (const glm::uvec3& tri : ps.triangles) {
            if (!own(tri.x) && !own(tri.y) && !own(tri.z)) continue;
            const glm::vec3 p[3] = {ps.positions[tri.x], ps.positions[tri.y], ps.positions[tri.z]};
            const glm::vec3 fn = glm::cross(p[1] - p[0], p[2] - p[0]);
            const float r = want_radii ? covering_radius(p[0], p[1], p[2]) : 0.0f;
            const std::uint32_t corner[3] = {tri.x, tri.y, tri.z};
            for (int c = 0; c < 3; ++c) {
              if (!own(corner[c])) continue;
              Accumulator& va = acc[corner[c]];
              va.normal += fn;
              va.radius = std::max(va.radius, r);
              if (want_curvature)  // relative to the vertex itself: no cancellation
                for (int o = 1; o < 3; ++o)
                  if (corner[(c + o) % 3] != corner[c]) va.ring.add(p[(c + o) % 3] - p[c]);
            }
          }
        }
      },
      threads, 1);
  if (want_normals) ps.normals.resize(n);
  if (want_radii) ps.radii.resize(n);
  if (want_curvature) ps.curvature.assign(n, 0.0f);
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      const Accumulator& va = acc[v];
      if (want_normals) {
        const float len = glm::length(va.normal);
        ps.normals[v] = len > 1e-30f && std::isfinite(len) ? va.normal / len : glm::vec3(0.0f);
      }
      if (want_radii) ps.radii[v] = va.radius;
      if (want_curvature && va.ring.count >= 3)
        ps.curvature[v] = detail::surface_variation(va.ring.covariance());
    }
  });
  if (want_radii) fill_missing_radii(ps.radii);  // vertices outside every face: the typical radius
}

// The splat radius from a neighbourhood: FOUND neighbours within D2K (the
// farthest's squared distance), spread as COV says (the point with its
// neighbours). On a surface, discs of radius r at local density rho = found
// / (pi d_k^2) leave a fraction exp(-rho pi r^2) of a randomly sampled
// surface uncovered: r = d_k sqrt(7 / found) -> 0.1%, no visible pinholes.
// Along a line (a wire, a scan line, a handful of collinear points: the
// spread across under 1 % of the spread along, which the sum of the
// covariance's principal 2x2 minors tells without an eigen solve) the
// points span L = sqrt(12 var) (a uniform segment's variance is L^2 / 12),
// their density is (found + 1) / L (the point itself is one of them), and
// the same 0.1 % is r = 3.45 / (2 rho) = 1.725 L / (found + 1): the
// surface's rule there drew discs several spacings wide, ten collinear
// points covering half a frame (issue 43, item 12).
float neighbourhood_radius(const detail::Sym3& cov, float d2k, int found) {
  const double trace = double(cov.xx) + cov.yy + cov.zz;
  const double minors = double(cov.xx) * cov.yy - double(cov.xy) * cov.xy +
                        double(cov.xx) * cov.zz - double(cov.xz) * cov.xz +
                        double(cov.yy) * cov.zz - double(cov.yz) * cov.yz;
  if (trace > 0.0 && minors <= 0.01 * trace * trace)
    return static_cast<float>(1.725 * std::sqrt(12.0 * trace) / (found + 1));
  return std::sqrt(d2k * 7.0f / static_cast<float>(found));
}

// What a point cloud's neighbours give: normals, radii, curvature of the
// points below QUERIED (the rest are neighbours only), from their k
// nearest within REACH, normals oriented with CENTROID.
struct NeighbourJob {
  int k;
  bool want_normals, want_radii, want_curvature;
  glm::vec3 centroid;
  std::size_t queried;
  float reach;  // the search's (NeighbourReach)
};

void from_neighbours(PointSet& ps, const NeighbourJob& job) {
  const std::size_t n = ps.size();
  const bool want_normals = job.want_normals, want_radii = job.want_radii,
             want_curvature = job.want_curvature;
  const int k = job.k;
  const detail::KnnGrid grid(ps.positions);
  if (want_normals) ps.normals.assign(n, glm::vec3(0.0f));
  if (want_radii) ps.radii.assign(n, 0.0f);
  if (want_curvature) ps.curvature.assign(n, 0.0f);
  const glm::vec3 c = job.centroid;
  const bool z_up = ps.frame.z_up;
  const auto visit = [&](std::uint32_t i, glm::vec3 p, int found, const glm::vec3* near,
                         const float* d2) {
    if (want_radii && found == 1) ps.radii[i] = std::sqrt(d2[0] * 7.0f);
    // No neighbour within the reach: at least that sparse (the cap then
    // holds it to the model's typical disc).
    if (want_radii && found == 0) ps.radii[i] = job.reach;
    if (found < 2) return;
    Moments m;
    for (int j = 0; j < found; ++j) m.add(near[j] - p);
    const Sym3 cov = m.covariance();
    if (want_radii) ps.radii[i] = neighbourhood_radius(cov, d2[found - 1], found);
    if (!want_normals && !want_curvature) return;
    if (!want_normals) {  // the eigenvalue alone is much cheaper than the full solve
      ps.curvature[i] = detail::surface_variation(cov);
      return;
    }
    const detail::Eigen3 eig = detail::eigen_symmetric(cov);
    if (want_curvature) ps.curvature[i] = detail::surface_variation(eig);
    {
      glm::vec3 nrm = eig.smallest;
      if (z_up && std::fabs(nrm.z) >= 0.2f) {
        // A survey (the format says z is up: LAS) was scanned from above or
        // beside: ground and roofs face up. Outward from the centroid would
        // turn a city's ground down, as the buildings lift the centroid.
        if (nrm.z < 0.0f) nrm = -nrm;
      } else if (glm::dot(nrm, p - c) < 0.0f) {
        nrm = -nrm;  // outward from the centroid
      }
      ps.normals[i] = nrm;
    }
  };
  grid.for_each_knn(k, visit, static_cast<std::uint32_t>(std::min<std::size_t>(job.queried, n)),
                    job.reach);
}

glm::vec3 centroid_of(const std::vector<glm::vec3>& positions) {
  glm::dvec3 sum(0.0);
  for (const auto& p : positions) sum += glm::dvec3(p);
  return glm::vec3(sum / static_cast<double>(std::max<std::size_t>(positions.size(), 1)));
}

// Which attributes OPTIONS and the file leave to compute (the file's own
// normalized and its radii completed as they are kept).
struct Wanted {
  bool normals, radii, curvature;
};

Wanted prepare(PointSet& ps, const AttributeOptions& options, bool fill_file_radii) {
  const std::size_t n = ps.size();
  if (options.recompute_normals) ps.normals.clear();
  if (options.recompute_radii) ps.radii.clear();
  if (ps.normals.size() != n) ps.normals.clear();
  if (ps.radii.size() != n) ps.radii.clear();
  if (ps.curvature.size() != n) ps.curvature.clear();
  if (ps.has_normals()) normalize_normals(ps.normals);
  if (ps.has_radii() && fill_file_radii) fill_missing_radii(ps.radii);
  const Wanted w{!ps.has_normals(), !ps.has_radii(), !ps.has_curvature()};
  if (w.normals) ps.frame.normals_estimated = true;
  return w;
}

}  // namespace

NeighbourReach::NeighbourReach(glm::vec3 lo, glm::vec3 hi) : lo_(lo) {
  constexpr int kCells = 64;
  const glm::vec3 extent = glm::max(hi - lo, glm::vec3(0.0f));
  // A little wider than the box, so that its far faces fall inside the grid.
  const float side = std::max({extent.x, extent.y, extent.z, 1e-30f}) * (1.0f + 1e-5f);
  cell_ = side / float(kCells);
  counts_.assign(std::size_t{kCells} * kCells * kCells, 0);
}

void NeighbourReach::count(std::span<const glm::vec3> points) {
  constexpr int kCells = 64;
  for (const glm::vec3& p : points) {
    const glm::ivec3 c = glm::clamp(glm::ivec3(glm::floor((p - lo_) / cell_)), glm::ivec3(0),
                                    glm::ivec3(kCells - 1));
    ++counts_[(std::size_t(c.z) * kCells + std::size_t(c.y)) * kCells + std::size_t(c.x)];
  }
}

float NeighbourReach::reach(int k) const {
  // The median occupied cell (by points); where it holds too few to tell a
  // spacing (a line, a sparse scatter), the grid is halved until it holds
  // 16 or the grid is one cell.
  std::vector<std::uint32_t> counts = counts_;
  float cell = cell_;
  for (int cells = 64;; cells /= 2, cell *= 2.0f) {
    std::vector<std::uint32_t> occupied;
    std::uint64_t total = 0;
    for (const std::uint32_t c : counts)
      if (c) occupied.push_back(c), total += c;
    if (occupied.empty()) return INFINITY;
    std::sort(occupied.begin(), occupied.end());
    std::uint64_t seen = 0;
    std::uint32_t median = occupied.back();
    for (const std::uint32_t c : occupied)
      if (2 * (seen += c) >= total) {
        median = c;
        break;
      }
    if (median >= 16 || cells == 1) {
      // k neighbours on a surface lie within about sqrt(k / pi) spacings;
      // four times that holds them in places 16 times sparser.
      const float spacing = cell / std::sqrt(float(median));
      return 4.0f * std::sqrt(float(std::max(k, 1)) / 3.14159265f) * spacing;
    }
    const int half = cells / 2;
    std::vector<std::uint32_t> coarser(std::size_t(half) * half * half, 0);
    for (int z = 0; z < cells; ++z)
      for (int y = 0; y < cells; ++y)
        for (int x = 0; x < cells; ++x)
          coarser[(std::size_t(z / 2) * half + std::size_t(y / 2)) * half + std::size_t(x / 2)] +=
              counts[(std::size_t(z) * cells + std::size_t(y)) * cells + std::size_t(x)];
    counts = std::move(coarser);
  }
}

void complete_attributes(PointSet& ps, const AttributeOptions& options, float reach) {
  const Wanted w = prepare(ps, options, true);
  if (!w.normals && !w.radii && !w.curvature) return;
  if (!ps.triangles.empty()) {
    from_faces(ps, w.normals, w.radii, w.curvature);
    return;
  }
  const int k = std::max(3, options.k);
  if (!(reach > 0.0f)) {
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& p : ps.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    NeighbourReach grid(lo, hi);
    grid.count(ps.positions);
    reach = grid.reach(k);
  }
  from_neighbours(ps, {k, w.normals, w.radii, w.curvature,
                       w.normals ? centroid_of(ps.positions) : glm::vec3(0.0f), ps.size(), reach});
  if (w.radii) {
    fill_missing_radii(ps.radii);
    cap_sparse_radii(ps.radii);
  }
}

bool complete_part_attributes(PointSet& ps, const AttributeOptions& options,
                              const CloudPart& part) {
  const Wanted w = prepare(ps, options, false);
  if (w.normals || w.radii || w.curvature)
    from_neighbours(ps, {std::max(3, options.k), w.normals, w.radii, w.curvature, part.centroid,
                         part.queried, part.reach});
  return w.radii;
}

void finish_part_radii(std::vector<float>& radii, float median, bool from_neighbours) {
  for (float& r : radii)
    if (!(r > 0.0f) || !std::isfinite(r)) r = median > 0.0f ? median : 1.0f;
  if (!from_neighbours || !(median > 0.0f)) return;
  const float cap = kSparseRadiusCap * median;
  for (float& r : radii) r = std::min(r, cap);
}

}  // namespace treecut
