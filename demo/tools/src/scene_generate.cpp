// Generated parts of scenes and the generated scenes (scene.hpp): the
// "building" and "ground" models a scene file may name, the city block of
// tens of thousands of instanced buildings and the hall of instanced scans,
// written as scene files, and their walkthroughs. Layouts are pure functions
// of (objects, seed); the points pure functions of (seed, index), sampled
// uniformly by area as the other scenes (generate_sampling.hpp).
#include "treecut/tools/scene_generate.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <glm/geometric.hpp>

#include "generate_sampling.hpp"
#include "treecut/error.hpp"

namespace treecut::tools {

using namespace scene_detail;

namespace {

enum BuildingMaterial { kWall, kRoof };

// The walls of the box [-w/2, w/2]^2 x [z0, z1], outward normals.
void box_walls(std::vector<Surface>& s, float w, float z0, float z1) {
  const float h = z1 - z0, a = 0.5f * w;
  s.push_back(quad({-a, -a, z0}, {w, 0, 0}, {0, 0, h}, kWall, 0));
  s.push_back(quad({a, -a, z0}, {0, w, 0}, {0, 0, h}, kWall, 1));
  s.push_back(quad({a, a, z0}, {-w, 0, 0}, {0, 0, h}, kWall, 2));
  s.push_back(quad({-a, a, z0}, {0, -w, 0}, {0, 0, h}, kWall, 3));
}

// Shortest text that reads back as the same float (the scene files are
// exact: a walkthrough or a test sees exactly what was written).
std::string num(float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

glm::vec3 palette(std::uint64_t seed) {
  static const glm::vec3 kFacades[4] = {
      {0.72f, 0.66f, 0.58f}, {0.55f, 0.60f, 0.68f}, {0.66f, 0.48f, 0.40f}, {0.80f, 0.78f, 0.72f}};
  return kFacades[seed % 4];
}

}  // namespace

std::vector<std::string> scene_generated_kinds() {
  return {"sphere", "terrain", "city", "plant", "building", "ground"};
}

PointSet generate_building(std::size_t points, std::uint64_t seed) {
  if (points == 0) throw InputError("generate_building: zero points requested");
  // Half the buildings have a set-back upper tier (from 0.6..0.8 of the
  // height, 0.55..0.8 of the footprint): a second silhouette for the same
  // lot, so a few models give a varied skyline.
  const bool tier = rnd(seed, 0, 1) < 0.5f;
  const float h1 = tier ? 0.6f + 0.2f * rnd(seed, 0, 2) : 1.0f;
  const float w2 = 0.55f + 0.25f * rnd(seed, 0, 3);
  std::vector<Surface> s;
  box_walls(s, 1.0f, 0.0f, h1);
  Surface roof = quad({-0.5f, -0.5f, h1}, {1, 0, 0}, {0, 1, 0}, kRoof, 4);
  if (tier) {
    // The lower roof is a ring: points under the upper tier are drawn again,
    // and only the free area counts (sample_scene's ground rule).
    roof.ground = true;
    roof.area = 1.0 - double(w2) * w2;
    s.push_back(roof);
    box_walls(s, w2, h1, 1.0f);
    s.push_back(quad({-0.5f * w2, -0.5f * w2, 1.0f}, {w2, 0, 0}, {0, w2, 0}, kRoof, 5));
  } else {
    s.push_back(roof);
  }
  const glm::vec3 facade = palette(seed);
  const Blocked under_tier = [w2](glm::vec3 p) {
    return std::abs(p.x) < 0.5f * w2 && std::abs(p.y) < 0.5f * w2;
  };
  return sample_scene(s, points, seed, under_tier, [&](const Surface& f, const Sample& x) {
    if (f.material == kRoof) return rgb(0.42f, 0.42f, 0.44f);
    // Darker at the foot, a lighter band below the roof line of each tier.
    const float top = x.p.z <= h1 ? h1 : 1.0f;
    const float shade = 0.8f + 0.2f * x.p.z + (top - x.p.z < 0.04f ? 0.12f : 0.0f);
    return rgb(facade * shade);
  });
}

PointSet generate_ground(std::size_t points, std::uint64_t seed) {
  if (points == 0) throw InputError("generate_ground: zero points requested");
  const std::vector<Surface> s = {quad({-0.5f, -0.5f, 0}, {1, 0, 0}, {0, 1, 0}, 0, 0)};
  return sample_scene(s, points, seed, nullptr, [&](const Surface&, const Sample& x) {
    const float grain = 0.04f * (rnd(seed,
                                     static_cast<std::uint64_t>(x.a * 4096.0f) * 4096u +
                                         static_cast<std::uint64_t>(x.b * 4096.0f),
                                     7) -
                                 0.5f);
    return rgb(0.36f + grain, 0.36f + grain, 0.37f + grain);
  });
}

PointSet generate_scene_model(std::string_view kind, std::size_t points, std::uint64_t seed) {
  if (kind == "building") return generate_building(points, seed);
  if (kind == "ground") return generate_ground(points, seed);
  if (kind == "field")
    throw InputError("generate: 'field' needs a source model (use `treecut gen field`)");
  for (const auto& k : scene_generated_kinds())
    if (k == kind) return generate_model(parse_model_kind(kind), points, seed);
  throw InputError("generate: unknown kind '" + std::string(kind) + "'");
}

// ---------------------------------------------------------------------------
// The city block.

CityBlockLayout city_block_layout(std::size_t objects, std::uint64_t seed) {
  if (objects == 0) throw InputError("city-block: needs at least one object");
  CityBlockLayout c;
  const std::size_t per_block = static_cast<std::size_t>(c.lots_x * c.lots_y);
  const std::size_t needed = (objects + per_block - 1) / per_block;
  // About square in metres: blocks_x / blocks_y ~ pitch_y / pitch_x.
  c.blocks_x = std::max(1, static_cast<int>(std::lround(std::sqrt(
                               double(needed) * double(c.pitch_y()) / double(c.pitch_x())))));
  c.blocks_y = static_cast<int>((needed + std::size_t(c.blocks_x) - 1) / std::size_t(c.blocks_x));
  c.blocks = static_cast<int>(needed);
  c.origin = -0.5f * glm::vec2(float(c.blocks_x) * c.pitch_x() - c.street,
                               float(c.blocks_y) * c.pitch_y() - c.street);
  const glm::vec2 half_extent = -c.origin;
  const float downtown = 0.35f * glm::length(half_extent);
  c.buildings.reserve(objects);
  for (std::size_t i = 0; i < objects; ++i) {
    const std::size_t block = i / per_block, lot = i % per_block;
    const int bx = static_cast<int>(block % std::size_t(c.blocks_x));
    const int by = static_cast<int>(block / std::size_t(c.blocks_x));
    const int lx = static_cast<int>(lot % std::size_t(c.lots_x));
    const int ly = static_cast<int>(lot / std::size_t(c.lots_x));
    CityBlockLayout::Building b;
    b.centre = c.origin + glm::vec2(float(bx) * c.pitch_x() + (float(lx) + 0.5f) * c.lot_w,
                                    float(by) * c.pitch_y() + (float(ly) + 0.5f) * c.lot_d);
    // Footprint 60..90 % of the lot (alleys between), taller downtown.
    const float wx = c.lot_w * (0.6f + 0.3f * rnd(seed, i, 1));
    const float wy = c.lot_d * (0.6f + 0.3f * rnd(seed, i, 2));
    const float d = glm::length(b.centre) / std::max(downtown, 1.0f);
    const float h = 6.0f + 18.0f * rnd(seed, i, 3) + 60.0f * std::exp(-d * d) * rnd(seed, i, 4);
    b.model = std::min(c.models - 1, static_cast<std::uint32_t>(rnd(seed, i, 5) * float(c.models)));
    b.quarter_turns = std::min(3, static_cast<int>(rnd(seed, i, 6) * 4.0f));
    // The model is scaled before it is turned: a quarter turn swaps x and y.
    b.size = b.quarter_turns % 2 ? glm::vec3(wy, wx, h) : glm::vec3(wx, wy, h);
    c.buildings.push_back(b);
  }
  return c;
}

std::string format_city_block_scene(const CityBlockLayout& c, std::uint64_t seed,
                                    std::size_t points) {
  std::string out(kSceneHeader);
  out += "\n# treecut gen city-block --objects " + std::to_string(c.buildings.size()) + " --seed " +
         std::to_string(seed) + " -n " + std::to_string(points) + "\n";
  out += "# " + std::to_string(c.buildings.size()) + " buildings, instances of " +
         std::to_string(c.models) + " building models, on " + std::to_string(c.blocks) +
         " ground tiles (one per block of " + std::to_string(c.lots_x) + " x " +
         std::to_string(c.lots_y) + " lots); metres, z up\n";
  for (std::uint32_t m = 0; m < c.models; ++m)
    out += "generate building" + std::to_string(m) + " building " + std::to_string(seed * 8 + m) +
           " " + std::to_string(points) + "\n";
  out += "generate ground ground " + std::to_string(seed) + " " + std::to_string(points) + "\n";
  out.reserve(out.size() + c.buildings.size() * 72);
  for (const auto& b : c.buildings) {
    out += "object building" + std::to_string(b.model) + " scale " + num(b.size.x) + " " +
           num(b.size.y) + " " + num(b.size.z);
    if (b.quarter_turns) out += " turn " + std::to_string(90 * b.quarter_turns);
    out += " translate " + num(b.centre.x) + " " + num(b.centre.y) + " 0\n";
  }
  // A tile per block reaching to the middle of the streets around it: the
  // tiles meet without a gap.
  for (int k = 0; k < c.blocks; ++k) {
    const int bx = k % c.blocks_x, by = k / c.blocks_x;
    const glm::vec2 centre =
        c.origin + glm::vec2((float(bx) + 0.5f) * c.pitch_x() - 0.5f * c.street,
                             (float(by) + 0.5f) * c.pitch_y() - 0.5f * c.street);
    out += "object ground scale " + num(c.pitch_x()) + " " + num(c.pitch_y()) + " 1 translate " +
           num(centre.x) + " " + num(centre.y) + " 0\n";
  }
  return out;
}

std::vector<WalkKey> city_block_walkthrough(const CityBlockLayout& c) {
  // Street centre lines: x line i runs west of block column i (i = blocks_x
  // is the east edge), y line j south of block row j.
  auto x_line = [&](int i) { return c.origin.x + float(i) * c.pitch_x() - 0.5f * c.street; };
  auto y_line = [&](int j) { return c.origin.y + float(j) * c.pitch_y() - 0.5f * c.street; };
  const int east = std::min(3, c.blocks_x), north = std::min(2, c.blocks_y);
  const int i0 = std::max(0, c.blocks_x / 2 - 1), j0 = std::max(0, c.blocks_y / 2 - 1);
  const int i1 = std::min(c.blocks_x, i0 + east), j1 = std::min(c.blocks_y, j0 + north);
  const std::vector<glm::vec2> route = {{x_line(i0), y_line(j0)},
                                        {x_line(i1), y_line(j0)},
                                        {x_line(i1), y_line(j1)},
                                        {x_line(i0), y_line(j1)}};
  float top = 0.0f;
  for (const auto& b : c.buildings) top = std::max(top, b.size.z);
  const glm::vec2 hi = -c.origin;
  return route_walkthrough(c.origin, hi, top, route, 1.7f, 10.0f, 15.0f);
}

// ---------------------------------------------------------------------------
// The hall.

HallLayout hall_layout(std::size_t objects, std::size_t sources, std::uint64_t seed) {
  if (objects == 0) throw InputError("hall: needs at least one object");
  if (sources == 0) throw InputError("hall: needs at least one --source");
  HallLayout h;
  h.cols = static_cast<int>(std::ceil(std::sqrt(double(objects))));
  h.rows = static_cast<int>((objects + std::size_t(h.cols) - 1) / std::size_t(h.cols));
  const glm::vec2 first(-0.5f * float(h.cols - 1) * h.spacing,
                        -0.5f * float(h.rows - 1) * h.spacing);
  h.lo = first - glm::vec2(0.5f * h.spacing);
  h.hi = -h.lo;
  for (std::size_t i = 0; i < objects; ++i) {
    HallLayout::Copy copy;
    const int c = static_cast<int>(i % std::size_t(h.cols)),
              r = static_cast<int>(i / std::size_t(h.cols));
    copy.centre = first + h.spacing * glm::vec2(float(c), float(r));
    copy.source = std::min(static_cast<std::uint32_t>(sources - 1),
                           static_cast<std::uint32_t>(rnd(seed, i, 11) * float(sources)));
    copy.height = 1.4f + 0.8f * rnd(seed, i, 12);
    copy.turn_deg = std::floor(360.0f * rnd(seed, i, 13));
    h.copies.push_back(copy);
  }
  return h;
}

std::string format_hall_scene(const HallLayout& h, const std::vector<HallSource>& sources,
                              std::uint64_t seed, std::size_t floor_points) {
  std::string out(kSceneHeader);
  out += "\n# treecut gen hall --objects " + std::to_string(h.copies.size()) + " --seed " +
         std::to_string(seed) + " -n " + std::to_string(floor_points) + "\n";
  out += "# " + std::to_string(h.rows) + " x " + std::to_string(h.cols) +
         " places 4 m apart, each an upright copy of a source (1.4..2.2 m tall, at most 1.2 m "
         "from its place); metres, z up\n";
  // Per source: the turn that stands it up (its up axis to +z), then the
  // move that puts the foot of its box at the origin; the scale that makes
  // it fit (height, and a horizontal radius of at most 1.2 m so the aisles
  // between places stay 1.6 m wide).
  struct Fit {
    std::string stand;  // "rotate ... translate ..."
    float height = 1.0f, radius = 1.0f;
  };
  std::vector<Fit> fits;
  for (std::size_t s = 0; s < sources.size(); ++s) {
    const HallSource& src = sources[s];
    out += "model source" + std::to_string(s) + " " + src.path.string() + "\n";
    const glm::vec3 u = glm::normalize(src.up), z(0, 0, 1);
    glm::vec3 axis(1, 0, 0);
    float deg = 0.0f;
    if (glm::dot(u, z) < 0.9999f) {
      if (glm::dot(u, z) > -0.9999f) axis = glm::normalize(glm::cross(u, z));
      deg = std::acos(std::clamp(glm::dot(u, z), -1.0f, 1.0f)) * 180.0f / kPi;
    }
    // Rodrigues, as the loader's rotate: the stood-up box's bounds.
    const float a = deg * kPi / 180.0f;
    auto turn = [&](glm::vec3 p) {
      return p * std::cos(a) + glm::cross(axis, p) * std::sin(a) +
             axis * glm::dot(axis, p) * (1.0f - std::cos(a));
    };
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (int c = 0; c < 8; ++c) {
      const glm::vec3 p =
          turn({c & 1 ? src.box_max.x : src.box_min.x, c & 2 ? src.box_max.y : src.box_min.y,
                c & 4 ? src.box_max.z : src.box_min.z});
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    Fit f;
    if (deg != 0.0f)
      f.stand = " rotate " + num(axis.x) + " " + num(axis.y) + " " + num(axis.z) + " " + num(deg);
    const glm::vec3 foot(0.5f * (lo.x + hi.x), 0.5f * (lo.y + hi.y), lo.z);
    f.stand += " translate " + num(-foot.x) + " " + num(-foot.y) + " " + num(-foot.z);
    f.height = std::max(hi.z - lo.z, 1e-6f);
    f.radius = std::max(0.5f * glm::length(glm::vec2(hi - lo)), 1e-6f);
    fits.push_back(f);
  }
  out +=
      "generate floor ground " + std::to_string(seed) + " " + std::to_string(floor_points) + "\n";
  for (const auto& c : h.copies) {
    const Fit& f = fits[c.source];
    const float scale = std::min(c.height / f.height, 1.2f / f.radius);
    out += "object source" + std::to_string(c.source) + f.stand + " scale " + num(scale);
    if (c.turn_deg != 0.0f) out += " turn " + num(c.turn_deg);
    out += " translate " + num(c.centre.x) + " " + num(c.centre.y) + " 0\n";
  }
  // Floor tiles of about 5 x 5 places, meeting without a gap.
  const int tx = std::max(1, (h.cols + 4) / 5), ty = std::max(1, (h.rows + 4) / 5);
  const glm::vec2 tile = (h.hi - h.lo) / glm::vec2(float(tx), float(ty));
  for (int j = 0; j < ty; ++j)
    for (int i = 0; i < tx; ++i) {
      const glm::vec2 centre = h.lo + tile * glm::vec2(float(i) + 0.5f, float(j) + 0.5f);
      out += "object floor scale " + num(tile.x) + " " + num(tile.y) + " 1 translate " +
             num(centre.x) + " " + num(centre.y) + " 0\n";
    }
  return out;
}

std::vector<WalkKey> hall_walkthrough(const HallLayout& h) {
  // Aisles run between rows (y) and columns (x), half a spacing from the
  // places; the walk starts west of the hall, goes along the aisle south of
  // the middle row for up to 5 places past the centre, two rows north and
  // back west.
  const float s = h.spacing;
  const int ka = std::max(0, h.rows / 2 - 1), kb = std::min(h.rows, ka + 2);
  const int ke = std::min(h.cols, h.cols / 2 + 5);
  const float ya = h.lo.y + float(ka) * s, yb = h.lo.y + float(kb) * s;
  const float xe = h.lo.x + float(ke) * s;
  const std::vector<glm::vec2> route = {{h.lo.x - s, ya}, {xe, ya}, {xe, yb}, {h.lo.x - s, yb}};
  return route_walkthrough(h.lo, h.hi, 2.2f, route, 1.6f, 2.0f, 3.0f);
}

SceneGenerator scene_generator() {
  return {scene_generated_kinds(), &generate_scene_model};
}

}  // namespace treecut::tools
