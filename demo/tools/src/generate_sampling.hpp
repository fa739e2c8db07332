// The sampling shared by the scene generators (generate_city.cpp,
// generate_plant.cpp): hashing per (seed, index, stream), colours, surfaces
// (quads, cylinders, discs) and the stratified sampling uniform by area.
// Internal to demo/tools/src.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <glm/geometric.hpp>
#include <numbers>
#include <vector>

#include "treecut/mix64.hpp"
#include "treecut/parallel.hpp"
#include "treecut/point_set.hpp"

namespace treecut::tools::scene_detail {

constexpr float kPi = std::numbers::pi_v<float>;

// Uniform in [0, 1) for (seed, index, stream); any number of streams.
inline float rnd(std::uint64_t seed, std::uint64_t i, std::uint64_t stream) {
  return static_cast<float>(splitmix64(splitmix64(seed * 0x100000001b3ull + stream) ^ i) >> 40) *
         (1.0f / 16777216.0f);
}

inline glm::u8vec4 rgb(float r, float g, float b) {
  auto c = [](float v) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
  };
  return {c(r), c(g), c(b), 255};
}

inline glm::u8vec4 rgb(glm::vec3 c) {
  return rgb(c.x, c.y, c.z);
}

inline glm::vec3 hue(float h) {
  const float r = std::clamp(std::abs(h * 6.0f - 3.0f) - 1.0f, 0.0f, 1.0f);
  const float g = std::clamp(2.0f - std::abs(h * 6.0f - 2.0f), 0.0f, 1.0f);
  const float b = std::clamp(2.0f - std::abs(h * 6.0f - 4.0f), 0.0f, 1.0f);
  return {r, g, b};
}

// One sampled surface. Quad: o + a u + b v, normal n. Cylinder (lateral
// surface): axis n from o, length len, radius r, (u, v) unit and
// perpendicular to n. Disc: centre o, normal n, radius r, (u, v) as above.
struct Surface {
  enum Kind { Quad, Cylinder, Disc } kind = Quad;
  glm::vec3 o{0.0f}, u{0.0f}, v{0.0f}, n{0.0f};
  float r = 0.0f, len = 0.0f;
  int material = 0;  // scene-specific: what the color callback keys on
  std::uint32_t id = 0;
  bool ground = false;  // sampled with the scene's footprint rejection
  double area = 0.0;
};

inline Surface quad(glm::vec3 o, glm::vec3 u, glm::vec3 v, int material, std::uint32_t id) {
  Surface s;
  s.o = o, s.u = u, s.v = v, s.n = glm::normalize(glm::cross(u, v));
  s.material = material, s.id = id;
  s.area = glm::length(glm::cross(u, v));
  return s;
}

// A unit vector pair perpendicular to the axis.
inline void basis(glm::vec3 n, glm::vec3& u, glm::vec3& v) {
  const glm::vec3 t = std::abs(n.z) < 0.9f ? glm::vec3(0, 0, 1) : glm::vec3(1, 0, 0);
  u = glm::normalize(glm::cross(t, n));
  v = glm::cross(n, u);
}

inline Surface cylinder(glm::vec3 base, glm::vec3 axis, float radius, float length, int material,
                        std::uint32_t id) {
  Surface s;
  s.kind = Surface::Cylinder;
  s.o = base, s.n = glm::normalize(axis), s.r = radius, s.len = length;
  basis(s.n, s.u, s.v);
  s.material = material, s.id = id;
  s.area = 2.0 * std::numbers::pi * radius * length;
  return s;
}

inline Surface disc(glm::vec3 centre, glm::vec3 normal, float radius, int material,
                    std::uint32_t id) {
  Surface s;
  s.kind = Surface::Disc;
  s.o = centre, s.n = glm::normalize(normal), s.r = radius;
  basis(s.n, s.u, s.v);
  s.material = material, s.id = id;
  s.area = std::numbers::pi * radius * radius;
  return s;
}

struct Sample {
  glm::vec3 p, n;
  float a, b;  // the surface parameters (along u / around, along v / axis)
};

inline Sample sample(const Surface& s, float a, float b) {
  switch (s.kind) {
    case Surface::Quad:
      return {s.o + a * s.u + b * s.v, s.n, a, b};
    case Surface::Cylinder: {
      const float t = 2.0f * kPi * a;
      const glm::vec3 radial = std::cos(t) * s.u + std::sin(t) * s.v;
      return {s.o + b * s.len * s.n + s.r * radial, radial, a, b};
    }
    case Surface::Disc: {
      const float t = 2.0f * kPi * a, rr = s.r * std::sqrt(b);
      return {s.o + rr * (std::cos(t) * s.u + std::sin(t) * s.v), s.n, a, b};
    }
  }
  return {s.o, s.n, a, b};
}

using Blocked = std::function<bool(glm::vec3)>;
using Shade = std::function<glm::u8vec4(const Surface&, const Sample&)>;

// Exactly n points, spread over the surfaces in proportion to their area
// (stratified: point i at the cumulative area (i + 0.5) / n), each uniform on
// its surface. A ground point in a footprint (`blocked`) is drawn again, up to
// 32 times (the ground's area counted is the free area, so the density stays
// uniform); after that (probability below 1e-9 for a footprint share of a
// half) it stays where it is, hidden under the building.
inline PointSet sample_scene(const std::vector<Surface>& surfaces, std::size_t n,
                             std::uint64_t seed, const Blocked& blocked, const Shade& shade) {
  std::vector<double> cumulative;
  cumulative.reserve(surfaces.size());
  double total = 0.0;
  for (const auto& s : surfaces) cumulative.push_back(total += s.area);
  PointSet ps;
  ps.positions.resize(n);
  ps.normals.resize(n);
  ps.colors.resize(n);
  parallel_for(n, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) {
      const double t = (static_cast<double>(i) + 0.5) / static_cast<double>(n) * total;
      const auto k = std::min<std::size_t>(
          static_cast<std::size_t>(std::lower_bound(cumulative.begin(), cumulative.end(), t) -
                                   cumulative.begin()),
          surfaces.size() - 1);
      const Surface& s = surfaces[k];
      Sample x = sample(s, rnd(seed, i, 0), rnd(seed, i, 1));
      for (std::uint64_t retry = 1; s.ground && retry <= 32 && blocked(x.p); ++retry)
        x = sample(s, rnd(seed, i, 2 * retry), rnd(seed, i, 2 * retry + 1));
      ps.positions[i] = x.p;
      ps.normals[i] = x.n;
      ps.colors[i] = shade(s, x);
    }
  });
  return ps;
}

// The point spacing of n points over the surfaces. Colour details narrower
// than about two spacings are left out: undersampled, they would be speckle
// (aliasing), not structure, so small models get plain walls and streets.
inline float spacing_of(const std::vector<Surface>& surfaces, std::size_t n) {
  double total = 0.0;
  for (const auto& s : surfaces) total += s.area;
  return static_cast<float>(std::sqrt(total / static_cast<double>(n)));
}

}  // namespace treecut::tools::scene_detail
