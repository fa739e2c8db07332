// The city: blocks of box buildings between streets, on a ground plane
// (generate.hpp, CityLayout; docs/scenes.md). Every point is a pure function
// of (seed, index): parallel, deterministic, points only.
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "generate_sampling.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::tools {

using namespace scene_detail;

namespace {

enum CityMaterial { kCityGround, kCityWall, kCityRoof };

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

}  // namespace

PointSet generate_city(std::size_t n, std::uint64_t seed) {
  return city_scene(n, seed);
}

}  // namespace treecut::tools
