// Scenes with depth complexity: a city of streets and buildings, a field of
// copies of a scanned model, an industrial plant of pipes and tanks. Each is a
// layout (a pure function of the seed) and a point sampling uniform by area
// over its visible surfaces, where every point is a pure function of (seed,
// index): parallel and deterministic, points only (no mesh is built), so tens
// of millions of points cost their 28 bytes each. Extents and densities:
// generate.hpp and docs/scenes.md.
#include <algorithm>
#include <cmath>
#include <functional>
#include <glm/geometric.hpp>
#include <numbers>

#include "treecut/error.hpp"
#include "treecut/generate.hpp"
#include "treecut/parallel.hpp"
#include "treecut/up_axis.hpp"

namespace treecut {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Uniform in [0, 1) for (seed, index, stream); any number of streams.
float rnd(std::uint64_t seed, std::uint64_t i, std::uint64_t stream) {
  return static_cast<float>(mix(mix(seed * 0x100000001b3ull + stream) ^ i) >> 40) *
         (1.0f / 16777216.0f);
}

glm::u8vec4 rgb(float r, float g, float b) {
  auto c = [](float v) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
  };
  return {c(r), c(g), c(b), 255};
}

glm::u8vec4 rgb(glm::vec3 c) {
  return rgb(c.x, c.y, c.z);
}

glm::vec3 hue(float h) {
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

Surface quad(glm::vec3 o, glm::vec3 u, glm::vec3 v, int material, std::uint32_t id) {
  Surface s;
  s.o = o, s.u = u, s.v = v, s.n = glm::normalize(glm::cross(u, v));
  s.material = material, s.id = id;
  s.area = glm::length(glm::cross(u, v));
  return s;
}

// A unit vector pair perpendicular to the axis.
void basis(glm::vec3 n, glm::vec3& u, glm::vec3& v) {
  const glm::vec3 t = std::abs(n.z) < 0.9f ? glm::vec3(0, 0, 1) : glm::vec3(1, 0, 0);
  u = glm::normalize(glm::cross(t, n));
  v = glm::cross(n, u);
}

Surface cylinder(glm::vec3 base, glm::vec3 axis, float radius, float length, int material,
                 std::uint32_t id) {
  Surface s;
  s.kind = Surface::Cylinder;
  s.o = base, s.n = glm::normalize(axis), s.r = radius, s.len = length;
  basis(s.n, s.u, s.v);
  s.material = material, s.id = id;
  s.area = 2.0 * std::numbers::pi * radius * length;
  return s;
}

Surface disc(glm::vec3 centre, glm::vec3 normal, float radius, int material, std::uint32_t id) {
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

Sample sample(const Surface& s, float a, float b) {
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
PointSet sample_scene(const std::vector<Surface>& surfaces, std::size_t n, std::uint64_t seed,
                      const Blocked& blocked, const Shade& shade) {
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

// ---------------------------------------------------------------- city

enum CityMaterial { kCityGround, kCityWall, kCityRoof };

// The point spacing of n points over the surfaces. Colour details narrower
// than about two spacings are left out: undersampled, they would be speckle
// (aliasing), not structure, so small models get plain walls and streets.
float spacing_of(const std::vector<Surface>& surfaces, std::size_t n) {
  double total = 0.0;
  for (const auto& s : surfaces) total += s.area;
  return static_cast<float>(std::sqrt(total / static_cast<double>(n)));
}

glm::u8vec4 city_ground(const CityLayout& c, glm::vec3 p, float spacing) {
  auto street = [&](float x, float& offset) {
    const float f = std::fmod(x + 1.0f, c.block_pitch);
    offset = std::min(f, c.block_pitch - f);
    return offset < 0.5f * c.street_width;
  };
  float ox = 0.0f, oy = 0.0f;
  const bool sx = street(p.x, ox), sy = street(p.y, oy);
  if ((sx || sy) && spacing < c.street_width / 3.0f) {
    // Dashed centre lines on the streets (not in the crossings).
    const bool line = spacing < 0.0008f &&
                      ((sy && !sx && oy < 0.001f && std::fmod(p.x + 10.0f, 0.02f) < 0.011f) ||
                       (sx && !sy && ox < 0.001f && std::fmod(p.y + 10.0f, 0.02f) < 0.011f));
    return line ? rgb(0.85f, 0.78f, 0.35f) : rgb(0.22f, 0.22f, 0.24f);
  }
  const int bi = std::clamp(static_cast<int>((p.x + 1.0f) / c.block_pitch), 0, c.blocks - 1);
  const int bj = std::clamp(static_cast<int>((p.y + 1.0f) / c.block_pitch), 0, c.blocks - 1);
  if (spacing < 0.01f && c.park[static_cast<std::size_t>(bj * c.blocks + bi)])
    return rgb(0.30f, 0.52f, 0.25f);
  const float edge = std::min(ox, oy) - 0.5f * c.street_width;
  return edge < c.setback && spacing < 0.002f ? rgb(0.62f, 0.61f, 0.58f) : rgb(0.48f, 0.47f, 0.45f);
}

}  // namespace

CityLayout city_layout(std::uint64_t seed) {
  CityLayout c;
  c.park.assign(static_cast<std::size_t>(c.blocks * c.blocks), false);
  for (int bj = 0; bj < c.blocks; ++bj)
    for (int bi = 0; bi < c.blocks; ++bi) {
      const auto b = static_cast<std::uint64_t>(bj * c.blocks + bi);
      const float x0 = -1.0f + c.block_pitch * static_cast<float>(bi) + 0.5f * c.street_width;
      const float y0 = -1.0f + c.block_pitch * static_cast<float>(bj) + 0.5f * c.street_width;
      const float side = c.block_pitch - c.street_width;
      // About one block in twelve is a park: an open stretch among the towers.
      if (rnd(seed, b, 100) < 0.08f) {
        c.park[b] = true;
        continue;
      }
      const int nx = 1 + static_cast<int>(rnd(seed, b, 101) * 2.0f);
      const int ny = 1 + static_cast<int>(rnd(seed, b, 102) * 2.0f);
      const float inner = side - 2.0f * c.setback;
      const float lot_x = (inner - c.alley * static_cast<float>(nx - 1)) / static_cast<float>(nx);
      const float lot_y = (inner - c.alley * static_cast<float>(ny - 1)) / static_cast<float>(ny);
      // Taller towards the centre (a downtown), heavy-tailed heights.
      const glm::vec2 centre(x0 + 0.5f * side, y0 + 0.5f * side);
      const float downtown = std::max(0.25f, 1.2f - 0.6f * glm::length(centre));
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const auto id = b * 16 + static_cast<std::uint64_t>(j * 4 + i);
          const float lx = x0 + c.setback + static_cast<float>(i) * (lot_x + c.alley);
          const float ly = y0 + c.setback + static_cast<float>(j) * (lot_y + c.alley);
          // A building fills most of its lot; the rest is a yard.
          const float fx = lot_x * (0.75f + 0.25f * rnd(seed, id, 103));
          const float fy = lot_y * (0.75f + 0.25f * rnd(seed, id, 104));
          const float h = (0.03f + 0.30f * std::pow(rnd(seed, id, 105), 2.5f)) * downtown + 0.012f;
          CityLayout::Building bd;
          // Placed at random in its lot: the facades of neighbours are not
          // coplanar (coplanar splats of two colours tie in depth and flicker).
          const float px = lx + (lot_x - fx) * rnd(seed, id, 108);
          const float py = ly + (lot_y - fy) * rnd(seed, id, 109);
          bd.lo = {px, py, 0.0f};
          bd.hi = {px + fx, py + fy, h};
          bd.style = static_cast<int>(rnd(seed, id, 106) * 4.0f);
          c.buildings.push_back(bd);
          c.block_of.push_back(static_cast<std::uint32_t>(b));
        }
    }
  return c;
}

namespace {

PointSet city_scene(std::size_t n, std::uint64_t seed) {
  const CityLayout c = city_layout(seed);
  std::vector<Surface> s;
  Surface ground = quad({-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, kCityGround, 0);
  ground.ground = true;
  ground.area = 4.0;
  for (const auto& b : c.buildings) ground.area -= (b.hi.x - b.lo.x) * (b.hi.y - b.lo.y);
  s.push_back(ground);
  for (std::uint32_t k = 0; k < c.buildings.size(); ++k) {
    const auto& b = c.buildings[k];
    const glm::vec3 d = b.hi - b.lo;
    s.push_back(quad({b.lo.x, b.lo.y, b.hi.z}, {d.x, 0, 0}, {0, d.y, 0}, kCityRoof, k));
    s.push_back(quad(b.lo, {d.x, 0, 0}, {0, 0, d.z}, kCityWall, k));                  // -y
    s.push_back(quad({b.hi.x, b.lo.y, 0}, {0, d.y, 0}, {0, 0, d.z}, kCityWall, k));   // +x
    s.push_back(quad({b.hi.x, b.hi.y, 0}, {-d.x, 0, 0}, {0, 0, d.z}, kCityWall, k));  // +y
    s.push_back(quad({b.lo.x, b.hi.y, 0}, {0, -d.y, 0}, {0, 0, d.z}, kCityWall, k));  // -x
  }
  // Footprint lookup per block for the ground's rejection.
  std::vector<std::uint32_t> first(static_cast<std::size_t>(c.blocks * c.blocks) + 1, 0);
  for (std::uint32_t b : c.block_of) ++first[b + 1];
  for (std::size_t b = 1; b < first.size(); ++b) first[b] += first[b - 1];
  const Blocked blocked = [&](glm::vec3 p) {
    const int bi = std::clamp(static_cast<int>((p.x + 1.0f) / c.block_pitch), 0, c.blocks - 1);
    const int bj = std::clamp(static_cast<int>((p.y + 1.0f) / c.block_pitch), 0, c.blocks - 1);
    const auto b = static_cast<std::size_t>(bj * c.blocks + bi);
    for (std::uint32_t k = first[b]; k < first[b + 1]; ++k) {
      const auto& bd = c.buildings[k];
      if (p.x >= bd.lo.x && p.x <= bd.hi.x && p.y >= bd.lo.y && p.y <= bd.hi.y) return true;
    }
    return false;
  };
  const float spacing = spacing_of(s, n);
  static const glm::vec3 facade[4] = {
      {0.78f, 0.72f, 0.60f}, {0.62f, 0.33f, 0.26f}, {0.50f, 0.60f, 0.70f}, {0.86f, 0.86f, 0.84f}};
  const Shade shade = [&](const Surface& f, const Sample& x) {
    if (f.material == kCityGround) return city_ground(c, x.p, spacing);
    const auto& b = c.buildings[f.id];
    const glm::vec3 base = facade[b.style];
    if (f.material == kCityRoof) return rgb(0.40f, 0.40f, 0.42f);
    // Storeys of 5 m (0.01) with a row of windows each: the walls read as
    // buildings and show their scale (from about 2 M points on: spacing < 0.0025).
    const float along = x.a * glm::length(f.u);
    const float fz = std::fmod(x.p.z, 0.01f) / 0.01f;
    const float fa = std::fmod(along, 0.012f) / 0.012f;
    const bool window =
        spacing < 0.0025f && x.p.z > 0.008f && fz > 0.3f && fz < 0.8f && fa > 0.2f && fa < 0.8f;
    const glm::vec3 col = window ? base * 0.45f + glm::vec3(0.05f, 0.07f, 0.10f) : base;
    return rgb(col);
  };
  return sample_scene(s, n, seed, blocked, shade);
}

// ---------------------------------------------------------------- plant

enum PlantMaterial { kPlantGround, kPlantTank, kPlantCap, kPlantPipe, kPlantRiser };

}  // namespace

PlantLayout plant_layout(std::uint64_t seed) {
  PlantLayout p;
  const float half = 0.5f * p.aisle_width;
  std::uint32_t id = 0;
  // Tanks: one to four per cell, on a 2 x 2 sub-grid, radius fitting it.
  for (int cj = 0; cj < p.cells; ++cj)
    for (int ci = 0; ci < p.cells; ++ci) {
      const auto cell = static_cast<std::uint64_t>(cj * p.cells + ci);
      const float x0 = -1.0f + p.cell_pitch * static_cast<float>(ci) + half + p.margin;
      const float y0 = -1.0f + p.cell_pitch * static_cast<float>(cj) + half + p.margin;
      const float side = p.cell_pitch - p.aisle_width - 2.0f * p.margin;
      const bool big = rnd(seed, cell, 200) < 0.3f;
      const int k = big ? 1 : 2;
      for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
          const auto t = cell * 8 + static_cast<std::uint64_t>(j * 2 + i);
          if (!big && rnd(seed, t, 201) < 0.2f) continue;  // an empty slot
          const float slot = side / static_cast<float>(k);
          const float r = 0.5f * slot * (0.6f + 0.35f * rnd(seed, t, 202));
          PlantLayout::Cylinder c;
          c.base = {x0 + slot * (static_cast<float>(i) + 0.5f),
                    y0 + slot * (static_cast<float>(j) + 0.5f), 0.0f};
          c.axis = {0, 0, 1};
          c.radius = r;
          c.length = (big ? 0.16f : 0.08f) + 0.16f * rnd(seed, t, 203);
          c.tank = true;
          c.id = id++;
          p.cylinders.push_back(c);
          // A feeder pipe from the tank to the nearest aisle along x, low.
          PlantLayout::Cylinder f;
          const bool east = i == k - 1 ? true : (i == 0 ? false : rnd(seed, t, 204) < 0.5f);
          const float edge = east ? x0 + side + p.margin : x0 - p.margin;
          const float from = c.base.x + (east ? 0.5f * r : -0.5f * r);
          f.radius = 0.004f + 0.004f * rnd(seed, t, 205);
          f.base = {std::min(from, edge), c.base.y + (rnd(seed, t, 206) - 0.5f) * r,
                    0.015f + 0.03f * rnd(seed, t, 207)};
          f.axis = {1, 0, 0};
          f.length = std::abs(edge - from);
          f.id = id++;
          p.cylinders.push_back(f);
        }
    }
  // Pipe racks over every inner aisle: along x at 0.045..0.08, along y at
  // 0.085..0.12, so the two directions cross without touching; off the
  // aisle's centre line, where the walkthrough's eye passes below them.
  for (int a = 1; a < p.cells; ++a) {
    const float centre = -1.0f + p.cell_pitch * static_cast<float>(a);
    for (int dir = 0; dir < 2; ++dir) {
      const int count =
          3 + static_cast<int>(rnd(seed, static_cast<std::uint64_t>(a * 2 + dir), 210) * 4.0f);
      for (int q = 0; q < count; ++q) {
        const auto t = static_cast<std::uint64_t>((a * 2 + dir) * 16 + q);
        PlantLayout::Cylinder c;
        c.radius = 0.004f + 0.007f * rnd(seed, t, 211);
        const float side = (q % 2 ? 1.0f : -1.0f);
        const float offset =
            side * (c.radius + 0.006f + (half - 2.0f * c.radius - 0.008f) * rnd(seed, t, 212));
        const float z = (dir == 0 ? 0.045f : 0.085f) + 0.035f * rnd(seed, t, 213);
        c.base = dir == 0 ? glm::vec3(-1.0f + half, centre + offset, z)
                          : glm::vec3(centre + offset, -1.0f + half, z);
        c.axis = dir == 0 ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
        c.length = 2.0f - 2.0f * half;
        c.id = id++;
        p.cylinders.push_back(c);
      }
    }
  }
  // Risers at the corners of the crossings: vertical pipes up to the racks.
  for (int aj = 1; aj < p.cells; ++aj)
    for (int ai = 1; ai < p.cells; ++ai) {
      const auto t = static_cast<std::uint64_t>(aj * p.cells + ai);
      const float sx = rnd(seed, t, 220) < 0.5f ? -1.0f : 1.0f;
      const float sy = rnd(seed, t, 221) < 0.5f ? -1.0f : 1.0f;
      PlantLayout::Cylinder c;
      c.radius = 0.006f;
      c.base = {-1.0f + p.cell_pitch * static_cast<float>(ai) + sx * (half - 0.008f),
                -1.0f + p.cell_pitch * static_cast<float>(aj) + sy * (half - 0.008f), 0.0f};
      c.axis = {0, 0, 1};
      c.length = 0.13f;
      c.id = id++;
      p.cylinders.push_back(c);
    }
  return p;
}

namespace {

PointSet plant_scene(std::size_t n, std::uint64_t seed) {
  const PlantLayout p = plant_layout(seed);
  std::vector<Surface> s;
  Surface ground = quad({-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, kPlantGround, 0);
  ground.ground = true;
  ground.area = 4.0;
  for (const auto& c : p.cylinders)
    if (c.tank) ground.area -= std::numbers::pi * c.radius * c.radius;
  s.push_back(ground);
  for (const auto& c : p.cylinders) {
    const int m = c.tank ? kPlantTank : (c.axis.z > 0.5f ? kPlantRiser : kPlantPipe);
    s.push_back(cylinder(c.base, c.axis, c.radius, c.length, m, c.id));
    if (c.tank) s.push_back(disc(c.base + c.length * c.axis, c.axis, c.radius, kPlantCap, c.id));
  }
  std::vector<const PlantLayout::Cylinder*> tanks;
  for (const auto& c : p.cylinders)
    if (c.tank) tanks.push_back(&c);
  const Blocked blocked = [&](glm::vec3 q) {
    const int ci = std::clamp(static_cast<int>((q.x + 1.0f) / p.cell_pitch), 0, p.cells - 1);
    const int cj = std::clamp(static_cast<int>((q.y + 1.0f) / p.cell_pitch), 0, p.cells - 1);
    for (const auto* t : tanks) {
      // Only the tanks of this cell can cover the point.
      const int ti =
          std::clamp(static_cast<int>((t->base.x + 1.0f) / p.cell_pitch), 0, p.cells - 1);
      const int tj =
          std::clamp(static_cast<int>((t->base.y + 1.0f) / p.cell_pitch), 0, p.cells - 1);
      if (ti != ci || tj != cj) continue;
      const glm::vec2 d(q.x - t->base.x, q.y - t->base.y);
      if (glm::dot(d, d) <= t->radius * t->radius) return true;
    }
    return false;
  };
  const float half = 0.5f * p.aisle_width;
  const float spacing = spacing_of(s, n);
  const Shade shade = [&](const Surface& f, const Sample& x) {
    switch (f.material) {
      case kPlantGround: {
        // Yellow lines along the aisles' edges on grey concrete.
        const float fx = std::fmod(x.p.x + 1.0f, p.cell_pitch),
                    fy = std::fmod(x.p.y + 1.0f, p.cell_pitch);
        const float ox = std::min(fx, p.cell_pitch - fx), oy = std::min(fy, p.cell_pitch - fy);
        const bool line =
            spacing < 0.002f && (std::abs(ox - half) < 0.002f || std::abs(oy - half) < 0.002f);
        return line ? rgb(0.85f, 0.75f, 0.15f) : rgb(0.55f, 0.55f, 0.53f);
      }
      case kPlantTank: {
        // White tanks with a coloured band near the top (which tank is which)
        // and darker seams every 0.02 of height.
        const glm::vec3 band = hue(rnd(seed, f.id, 230));
        const float seam = std::fmod(x.p.z, 0.02f);
        if (x.b > 0.78f && x.b < 0.88f) return rgb(band);
        return seam < 0.0012f && spacing < 0.0006f ? rgb(0.55f, 0.56f, 0.58f)
                                                   : rgb(0.86f, 0.87f, 0.88f);
      }
      case kPlantCap:
        return rgb(0.70f, 0.71f, 0.72f);
      case kPlantRiser:
        return rgb(0.35f, 0.36f, 0.38f);
      default: {
        // Pipes by service: red, yellow, green, blue, orange.
        static const glm::vec3 service[5] = {{0.75f, 0.15f, 0.12f},
                                             {0.90f, 0.78f, 0.15f},
                                             {0.20f, 0.60f, 0.25f},
                                             {0.20f, 0.35f, 0.75f},
                                             {0.90f, 0.50f, 0.15f}};
        const glm::vec3 c = service[f.id % 5];
        return rgb(c);
      }
    }
  };
  return sample_scene(s, n, seed, blocked, shade);
}

}  // namespace

// ---------------------------------------------------------------- field

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

PointSet generate_city(std::size_t n, std::uint64_t seed) {
  return city_scene(n, seed);
}
PointSet generate_plant(std::size_t n, std::uint64_t seed) {
  return plant_scene(n, seed);
}

}  // namespace treecut
