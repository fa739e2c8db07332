// The field: copies of a scanned model on a ground plane, turned and scaled
// by seed (generate.hpp, FieldLayout, FieldSource; docs/scenes.md). Every
// point is a pure function of (seed, index): parallel, deterministic, points
// only (the copies are sampled from the one normalized source).
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "generate_sampling.hpp"
#include "treecut/error.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/up_axis.hpp"

namespace treecut::tools {

using namespace scene_detail;

FieldLayout field_layout(std::uint64_t seed) {
  FieldLayout f;
  for (int j = 0; j < f.cells; ++j)
    for (int i = 0; i < f.cells; ++i) {
      const auto c = static_cast<std::uint64_t>(j * f.cells + i);
      if (rnd(seed, c, 300) < 0.1f) continue;  // a clearing
      FieldLayout::Copy copy;
      copy.radius = f.min_radius + (f.max_radius - f.min_radius) * rnd(seed, c, 301);
      // The copy's circle stays inside its cell minus the lane: the lanes
      // between the cells are free for the walkthrough.
      const float room = 0.5f * f.cell_pitch - 0.5f * f.lane_width - copy.radius;
      copy.centre = {-1.0f + f.cell_pitch * (static_cast<float>(i) + 0.5f) +
                         room * (2.0f * rnd(seed, c, 302) - 1.0f),
                     -1.0f + f.cell_pitch * (static_cast<float>(j) + 0.5f) +
                         room * (2.0f * rnd(seed, c, 303) - 1.0f)};
      copy.angle = 2.0f * kPi * rnd(seed, c, 304);
      f.copies.push_back(copy);
    }
  return f;
}

FieldSource prepare_field_source(const PointSet& source) {
  if (source.size() == 0) throw InputError("field: the source model has no points");
  if (source.normals.size() != source.size())
    throw InputError("field: the source model needs normals (complete_attributes)");
  FieldSource f;
  // Turn the model so its up axis (detected from the data, as render does) is +z.
  const UpAxis up = detect_up_axis(source.positions, source.normals);
  const glm::vec3 zu = up.vector();
  glm::vec3 xu, yu;
  basis(zu, xu, yu);
  auto turn = [&](glm::vec3 v) {
    return glm::vec3(glm::dot(v, xu), glm::dot(v, yu), glm::dot(v, zu));
  };
  f.points.positions.resize(source.size());
  f.points.normals.resize(source.size());
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (std::size_t i = 0; i < source.size(); ++i) {
    f.points.positions[i] = turn(source.positions[i]);
    f.points.normals[i] = turn(source.normals[i]);
    lo = glm::min(lo, f.points.positions[i]);
    hi = glm::max(hi, f.points.positions[i]);
  }
  // Standing on z = 0, centred in x and y, unit radius about the vertical axis.
  const glm::vec3 shift(0.5f * (lo.x + hi.x), 0.5f * (lo.y + hi.y), lo.z);
  float radius = 0.0f;
  for (auto& p : f.points.positions) {
    p -= shift;
    radius = std::max(radius, std::hypot(p.x, p.y));
  }
  if (!(radius > 0.0f)) throw InputError("field: the source model has no horizontal extent");
  for (auto& p : f.points.positions) p /= radius;
  f.points.colors = source.colors;
  f.points.triangles = source.triangles;
  // Surface area: the triangles' when the model has faces (then copies are
  // sampled on the faces), else a disc per point of the splat radius.
  f.area.reserve(source.triangles.empty() ? source.size() : source.triangles.size());
  double total = 0.0;
  if (!source.triangles.empty()) {
    for (const auto& t : source.triangles) {
      const auto& P = f.points.positions;
      total += 0.5 * glm::length(glm::cross(P[t.y] - P[t.x], P[t.z] - P[t.x]));
      f.area.push_back(total);
    }
  } else {
    if (source.radii.size() != source.size())
      throw InputError("field: a source without faces needs splat radii (complete_attributes)");
    for (std::size_t i = 0; i < source.size(); ++i) {
      // Splats overlap (radius ~ spacing): a quarter of the disc is the
      // point's share of the surface.
      const double r = source.radii[i] / radius;
      total += 0.25 * std::numbers::pi * r * r;
      f.area.push_back(total);
      f.jitter.push_back(0.5f * source.radii[i] / radius);
    }
  }
  f.unit_area = total;
  return f;
}

PointSet generate_field(const FieldSource& src, std::size_t n, std::uint64_t seed) {
  if (n == 0) throw InputError("generate_model: zero points requested");
  const FieldLayout f = field_layout(seed);
  // The ground and every copy by area (a copy's area grows with its scale squared).
  std::vector<double> cumulative;
  // The ground is counted whole: a copy hides only the little it stands on.
  double total = 4.0;
  cumulative.push_back(total);
  for (const auto& c : f.copies) cumulative.push_back(total += src.unit_area * c.radius * c.radius);
  PointSet ps;
  ps.positions.resize(n);
  ps.normals.resize(n);
  ps.colors.resize(n);
  const auto& P = src.points.positions;
  const auto& N = src.points.normals;
  const bool faces = !src.points.triangles.empty();
  parallel_for(n, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) {
      const double t = (static_cast<double>(i) + 0.5) / static_cast<double>(n) * total;
      const auto k = static_cast<std::size_t>(
          std::lower_bound(cumulative.begin(), cumulative.end(), t) - cumulative.begin());
      if (k == 0 || f.copies.empty()) {
        // Grass: green, a little varied.
        const glm::vec3 p(-1.0f + 2.0f * rnd(seed, i, 0), -1.0f + 2.0f * rnd(seed, i, 1), 0.0f);
        ps.positions[i] = p;
        ps.normals[i] = {0, 0, 1};
        const float g = 0.8f + 0.4f * rnd(seed, i, 2);
        ps.colors[i] = rgb(0.28f * g, 0.50f * g, 0.22f * g);
        continue;
      }
      const auto& copy = f.copies[std::min(k - 1, f.copies.size() - 1)];
      // A point of the source surface: on a face (uniform by area), or a
      // source point moved in its tangent plane within its splat.
      const double pick = static_cast<double>(rnd(seed, i, 3)) * src.unit_area;
      const auto e = std::min<std::size_t>(
          static_cast<std::size_t>(std::lower_bound(src.area.begin(), src.area.end(), pick) -
                                   src.area.begin()),
          src.area.size() - 1);
      glm::vec3 p, nn;
      glm::u8vec4 col{200, 200, 200, 255};
      if (faces) {
        const auto& tri = src.points.triangles[e];
        float a = rnd(seed, i, 4), b = rnd(seed, i, 5);
        if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
        const float w = 1.0f - a - b;
        p = w * P[tri.x] + a * P[tri.y] + b * P[tri.z];
        nn = w * N[tri.x] + a * N[tri.y] + b * N[tri.z];
        if (glm::dot(nn, nn) < 1e-12f) nn = glm::cross(P[tri.y] - P[tri.x], P[tri.z] - P[tri.x]);
        if (!src.points.colors.empty()) col = src.points.colors[tri.x];
      } else {
        p = P[e];
        nn = N[e];
        if (!src.jitter.empty() && glm::dot(nn, nn) > 0.0f) {
          glm::vec3 u, v;
          basis(glm::normalize(nn), u, v);
          const float ang = 2.0f * kPi * rnd(seed, i, 4),
                      rr = src.jitter[e] * std::sqrt(rnd(seed, i, 5));
          p += rr * (std::cos(ang) * u + std::sin(ang) * v);
        }
        if (!src.points.colors.empty()) col = src.points.colors[e];
      }
      nn = glm::dot(nn, nn) > 0.0f ? glm::normalize(nn) : glm::vec3(0, 0, 1);
      // Each copy turned about z and scaled; tinted so copies are told apart.
      const float cs = std::cos(copy.angle), sn = std::sin(copy.angle);
      auto rot = [&](glm::vec3 v) {
        return glm::vec3(cs * v.x - sn * v.y, sn * v.x + cs * v.y, v.z);
      };
      // A point cloud's tangential jitter can dip below the ground at the
      // copy's foot: it stays on the ground (z = 0), where the copy stands.
      p.z = std::max(p.z, 0.0f);
      ps.positions[i] = glm::vec3(copy.centre, 0.0f) + copy.radius * rot(p);
      ps.normals[i] = rot(nn);
      const auto idx = static_cast<std::uint64_t>(&copy - f.copies.data());
      const glm::vec3 tint = 0.55f * glm::vec3(col) / 255.0f + 0.45f * hue(rnd(seed, idx, 305));
      ps.colors[i] = rgb(tint);
    }
  });
  return ps;
}

}  // namespace treecut::tools
