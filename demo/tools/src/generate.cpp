// Procedural models: a sphere and a fractal terrain; the scenes (city, field,
// plant) are in generate_city.cpp, generate_plant.cpp and generate_field.cpp. Every
// point is a pure function of (seed, index), so generation is parallel and
// deterministic.
#include "treecut/tools/generate.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "treecut/error.hpp"
#include "treecut/mix64.hpp"
#include "treecut/parallel.hpp"

namespace treecut::tools {

namespace {

// Uniform in [0, 1) from a hash of the arguments.
float unit(std::uint64_t seed, std::uint64_t i, std::uint64_t stream) {
  return static_cast<float>(splitmix64(seed ^ splitmix64(i * 4 + stream)) >> 40) *
         (1.0f / 16777216.0f);
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

}  // namespace

ModelKind parse_model_kind(std::string_view name) {
  if (name == "sphere") return ModelKind::Sphere;
  if (name == "terrain") return ModelKind::Terrain;
  if (name == "city") return ModelKind::City;
  if (name == "field") return ModelKind::Field;
  if (name == "plant") return ModelKind::Plant;
  throw InputError("unknown model kind '" + std::string(name) +
                   "' (sphere, terrain, city, field or plant)");
}

std::vector<std::string> model_kind_names() {
  return {"sphere", "terrain", "city", "field", "plant"};
}

PointSet generate_model(ModelKind kind, std::size_t points, std::uint64_t seed) {
  if (points == 0) throw InputError("generate_model: zero points requested");
  switch (kind) {
    case ModelKind::Sphere:
      return sphere(points, seed);
    case ModelKind::Terrain:
      return terrain(points, seed);
    case ModelKind::City:
      return generate_city(points, seed);
    case ModelKind::Plant:
      return generate_plant(points, seed);
    case ModelKind::Field:
      throw InputError("a field needs a source model (treecut gen field --source PLY)");
  }
  throw InputError("generate_model: unknown kind");
}

void add_survey_attributes(PointSet& points, ModelKind kind) {
  PointAttribute intensity;
  intensity.name = "intensity";
  intensity.type = ValueType::u16;
  intensity.values.resize(points.size(), 32768.0f);
  if (points.has_colors()) {
    for (std::size_t i = 0; i < points.size(); ++i) {
      const glm::vec3 c = glm::vec3(points.colors[i]) / 255.0f;
      intensity.values[i] = std::round(65535.0f * (0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z));
    }
  }
  points.attributes.push_back(std::move(intensity));
  if (kind == ModelKind::City) {
    // The city's ground is the plane z = 0; roofs and walls rise from it.
    PointAttribute cls;
    cls.name = "classification";
    cls.kind = AttributeKind::category;
    cls.type = ValueType::u8;
    cls.values.resize(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      cls.values[i] = points.positions[i].z > 1e-5f ? 6.0f : 2.0f;
    }
    points.attributes.push_back(std::move(cls));
  }
}

}  // namespace treecut::tools
