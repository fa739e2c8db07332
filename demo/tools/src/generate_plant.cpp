// The plant: tanks, feeder pipes, pipe racks over the aisles and risers on a
// ground plane (generate.hpp, PlantLayout; docs/scenes.md). Every point is a
// pure function of (seed, index): parallel, deterministic, points only.
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "generate_sampling.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::tools {

using namespace scene_detail;

namespace {

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

PointSet generate_plant(std::size_t n, std::uint64_t seed) {
  return plant_scene(n, seed);
}

}  // namespace treecut::tools
