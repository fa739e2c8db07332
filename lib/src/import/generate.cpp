// Procedural models: a sphere, a fractal terrain and a city of boxes. Every
// point is a pure function of (seed, index), so generation is parallel and
// deterministic.
#include "treecut/generate.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "treecut/error.hpp"
#include "treecut/parallel.hpp"

namespace treecut {

namespace {

std::uint64_t hash64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Uniform in [0, 1) from a hash of the arguments.
float unit(std::uint64_t seed, std::uint64_t i, std::uint64_t stream) {
  return static_cast<float>(hash64(seed ^ hash64(i * 4 + stream)) >> 40) * (1.0f / 16777216.0f);
}

glm::u8vec4 rgb(float r, float g, float b) {
  auto c = [](float v) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
  };
  return {c(r), c(g), c(b), 255};
}

PointSet make(std::size_t n) {
  PointSet ps;
  ps.positions.resize(n);
  ps.normals.resize(n);
  ps.colors.resize(n);
  return ps;
}

PointSet sphere(std::size_t n, std::uint64_t seed) {
  PointSet ps = make(n);
  const float golden = static_cast<float>(M_PI) * (3.0f - std::sqrt(5.0f));
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      // Fibonacci lattice: near-uniform spacing, with a little jitter.
      const float z = 1.0f - 2.0f * (static_cast<float>(i) + 0.5f) / static_cast<float>(n);
      const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
      const float phi = golden * static_cast<float>(i) + 0.2f * unit(seed, i, 0);
      const glm::vec3 p(r * std::cos(phi), r * std::sin(phi), z);
      ps.positions[i] = p;
      ps.normals[i] = p;
      const float t = 0.5f * (z + 1.0f);
      const float band = 0.5f + 0.5f * std::sin(12.0f * std::asin(z));
      ps.colors[i] = rgb(0.25f + 0.6f * t, 0.35f + 0.3f * band, 0.85f - 0.6f * t);
    }
  });
  return ps;
}

// Value noise on an integer lattice with smooth interpolation, summed over octaves.
float lattice(std::uint64_t seed, int x, int y) {
  const auto key = (static_cast<std::uint64_t>(static_cast<std::uint32_t>(x)) << 32) |
                   static_cast<std::uint32_t>(y);
  return unit(seed, key, 3) * 2.0f - 1.0f;
}

float value_noise(std::uint64_t seed, float x, float y) {
  const float fx = std::floor(x), fy = std::floor(y);
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  auto s = [](float t) { return t * t * (3.0f - 2.0f * t); };
  const float tx = s(x - fx), ty = s(y - fy);
  const float a = lattice(seed, ix, iy), b = lattice(seed, ix + 1, iy);
  const float c = lattice(seed, ix, iy + 1), d = lattice(seed, ix + 1, iy + 1);
  return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

float terrain_height(std::uint64_t seed, float x, float y) {
  float h = 0.0f, amp = 0.35f, freq = 2.0f;
  for (int o = 0; o < 7; ++o, amp *= 0.5f, freq *= 2.0f)
    h += amp * value_noise(seed + static_cast<std::uint64_t>(o), x * freq, y * freq);
  return h;
}

PointSet terrain(std::size_t n, std::uint64_t seed) {
  PointSet ps = make(n);
  const auto side = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n))));
  const float step = 2.0f / static_cast<float>(side);
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const float x = -1.0f + step * (static_cast<float>(i % side) + unit(seed, i, 0));
      const float y = -1.0f + step * (static_cast<float>(i / side) + unit(seed, i, 1));
      const float h = terrain_height(seed, x, y);
      const float eps = 0.5f * step;
      const float dx =
          (terrain_height(seed, x + eps, y) - terrain_height(seed, x - eps, y)) / (2 * eps);
      const float dy =
          (terrain_height(seed, x, y + eps) - terrain_height(seed, x, y - eps)) / (2 * eps);
      ps.positions[i] = {x, y, h};
      ps.normals[i] = glm::normalize(glm::vec3(-dx, -dy, 1.0f));
      const float t = std::clamp((h + 0.4f) / 0.8f, 0.0f, 1.0f);
      ps.colors[i] = t < 0.5f   ? rgb(0.2f + 0.4f * t, 0.45f + 0.2f * t, 0.15f)
                     : t < 0.8f ? rgb(0.45f, 0.35f, 0.25f)
                                : rgb(0.95f, 0.95f, 0.97f);
    }
  });
  return ps;
}

// A grid of G x G box buildings on a ground square [-1, 1]^2 (z up). Points are
// spread over all visible surfaces in proportion to their area.
PointSet city(std::size_t n, std::uint64_t seed) {
  constexpr int G = 12;
  constexpr float cell = 2.0f / G, footprint = 0.6f * cell;
  struct Box {
    glm::vec2 lo, hi;
    float height;
    glm::u8vec4 color;
  };
  std::vector<Box> boxes;
  for (int j = 0; j < G; ++j)
    for (int i = 0; i < G; ++i) {
      const auto id = static_cast<std::uint64_t>(j * G + i);
      const glm::vec2 c(-1.0f + cell * (static_cast<float>(i) + 0.5f),
                        -1.0f + cell * (static_cast<float>(j) + 0.5f));
      const float h = 0.08f + 0.5f * std::pow(unit(seed, id, 2), 2.0f);
      boxes.push_back(
          {c - 0.5f * footprint, c + 0.5f * footprint, h,
           rgb(0.5f + 0.4f * unit(seed, id, 0), 0.5f + 0.3f * unit(seed, id, 1), 0.55f)});
    }
  // Surfaces: ground (minus footprints), then per box a roof and four walls.
  struct Surface {
    glm::vec3 origin, u, v, normal;
    glm::u8vec4 color;
    float area;
  };
  std::vector<Surface> surfaces;
  surfaces.push_back(
      {{-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 1}, rgb(0.45f, 0.47f, 0.45f), 4.0f});
  for (const Box& bx : boxes) {
    const glm::vec2 s = bx.hi - bx.lo;
    const float h = bx.height;
    surfaces.push_back({{bx.lo, h}, {s.x, 0, 0}, {0, s.y, 0}, {0, 0, 1}, bx.color, s.x * s.y});
    surfaces.push_back({{bx.lo, 0}, {s.x, 0, 0}, {0, 0, h}, {0, -1, 0}, bx.color, s.x * h});
    surfaces.push_back(
        {{bx.hi.x, bx.lo.y, 0}, {0, s.y, 0}, {0, 0, h}, {1, 0, 0}, bx.color, s.y * h});
    surfaces.push_back({{bx.hi, 0}, {-s.x, 0, 0}, {0, 0, h}, {0, 1, 0}, bx.color, s.x * h});
    surfaces.push_back(
        {{bx.lo.x, bx.hi.y, 0}, {0, -s.y, 0}, {0, 0, h}, {-1, 0, 0}, bx.color, s.y * h});
  }
  std::vector<double> cumulative;
  double total = 0.0;
  for (const auto& s : surfaces) cumulative.push_back(total += s.area);
  PointSet ps = make(n);
  auto inside_footprint = [&](glm::vec3 p) {
    const int i = std::clamp(static_cast<int>((p.x + 1.0f) / cell), 0, G - 1);
    const int j = std::clamp(static_cast<int>((p.y + 1.0f) / cell), 0, G - 1);
    const Box& bx = boxes[static_cast<std::size_t>(j * G + i)];
    return p.x > bx.lo.x && p.x < bx.hi.x && p.y > bx.lo.y && p.y < bx.hi.y;
  };
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      // Stratified choice of the surface, then a uniform point on it; ground
      // points under a building are re-drawn on that building's roof.
      const double t = (static_cast<double>(i) + 0.5) / static_cast<double>(n) * total;
      const auto k = static_cast<std::size_t>(
          std::lower_bound(cumulative.begin(), cumulative.end(), t) - cumulative.begin());
      const Surface* s = &surfaces[std::min(k, surfaces.size() - 1)];
      glm::vec3 p = s->origin + unit(seed, i, 0) * s->u + unit(seed, i, 1) * s->v;
      if (s == &surfaces[0] && inside_footprint(p)) {
        const int bi = std::clamp(static_cast<int>((p.x + 1.0f) / cell), 0, G - 1);
        const int bj = std::clamp(static_cast<int>((p.y + 1.0f) / cell), 0, G - 1);
        s = &surfaces[1 + 5 * static_cast<std::size_t>(bj * G + bi)];
        p = s->origin + unit(seed, i, 2) * s->u + unit(seed, i, 3) * s->v;
      }
      ps.positions[i] = p;
      ps.normals[i] = s->normal;
      ps.colors[i] = s->color;
    }
  });
  return ps;
}

}  // namespace

ModelKind parse_model_kind(std::string_view name) {
  if (name == "sphere") return ModelKind::Sphere;
  if (name == "terrain") return ModelKind::Terrain;
  if (name == "city") return ModelKind::City;
  throw InputError("unknown model kind '" + std::string(name) + "' (sphere, terrain or city)");
}

std::vector<std::string> model_kind_names() {
  return {"sphere", "terrain", "city"};
}

PointSet generate_model(ModelKind kind, std::size_t points, std::uint64_t seed) {
  if (points == 0) throw InputError("generate_model: zero points requested");
  switch (kind) {
    case ModelKind::Sphere:
      return sphere(points, seed);
    case ModelKind::Terrain:
      return terrain(points, seed);
    case ModelKind::City:
      return city(points, seed);
  }
  throw InputError("generate_model: unknown kind");
}

}  // namespace treecut
