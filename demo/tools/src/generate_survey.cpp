// The survey generator (survey.hpp). The world is a few pure functions of
// the seed and a map position: the ground's height, a grid of 80 m blocks
// (roads along their borders; a block is built on, wooded or open) and a
// 7 m grid of tree sites. A tile samples pulses at random places of its
// area, as a scanner's pulses land, and records the returns each pulse gets
// from the first surface it meets: a roof, a crown (and through it, the
// crown's inside and the ground) or the ground.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "treecut/mix64.hpp"
#include "treecut/tools/survey.hpp"

namespace treecut::tools {

namespace {

constexpr double kBlock = 80.0;  // block pitch, metres
constexpr double kRoad = 5.0;    // half a road's width: roads run along block borders
constexpr double kSite = 7.0;    // tree site pitch
constexpr double kLine = 400.0;  // flight line spacing (lines run north-south)
constexpr double kAltitude = 1100.0;
constexpr double kSpeed = 65.0;  // m/s over the ground

// ASPRS classes (LAS 1.4 R15, table 17).
constexpr float kGround = 2, kVegetation = 5, kBuilding = 6, kRoadSurface = 11;

// Uniform in [0, 1) for (seed, a, b, stream): the world's fixed features.
double hash01(std::uint64_t seed, std::int64_t a, std::int64_t b, std::uint64_t stream) {
  const std::uint64_t h = splitmix64(splitmix64(seed ^ (stream * 0x9e3779b97f4a7c15ull)) ^
                                     splitmix64(static_cast<std::uint64_t>(a) * 0x100000001b3ull) ^
                                     static_cast<std::uint64_t>(b));
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

// The pulses' own randomness: a sequence per tile.
class Random {
 public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  double next() {
    state_ += 0x9e3779b97f4a7c15ull;
    return static_cast<double>(splitmix64(state_) >> 11) * 0x1.0p-53;
  }
  // Roughly normal: the sum of three uniforms, sigma 1.
  double normal() { return (next() + next() + next() - 1.5) * 2.0; }

 private:
  std::uint64_t state_;
};

class World {
 public:
  explicit World(std::uint64_t seed) : seed_(seed) {
    for (std::size_t i = 0; i < phase_.size(); ++i) phase_[i] = 6.2831853 * hash01(seed, 0, 0, i);
  }

  // Gentle hills: tens of metres over kilometres, a metre over tens of metres.
  [[nodiscard]] double ground(double x, double y) const {
    return 25.0 * std::sin(x / 610.0 + phase_[0]) * std::cos(y / 770.0 + phase_[1]) +
           7.0 * std::sin((x + 0.6 * y) / 190.0 + phase_[2]) +
           1.5 * std::sin(x / 41.0 + phase_[3]) * std::sin(y / 53.0 + phase_[4]);
  }

  [[nodiscard]] static bool on_road(double x, double y) {
    const double u = x - kBlock * std::floor(x / kBlock), v = y - kBlock * std::floor(y / kBlock);
    return u < kRoad || u > kBlock - kRoad || v < kRoad || v > kBlock - kRoad;
  }

  enum class Block { open, built, wooded };
  [[nodiscard]] Block block(std::int64_t bx, std::int64_t by) const {
    const double u = hash01(seed_, bx, by, 1);
    return u < 0.4 ? Block::built : u < 0.6 ? Block::wooded : Block::open;
  }

  struct Roof {
    bool hit = false;
    double z = 0.0;
    int palette = 0;
  };
  // The building of the block at (x, y), if (x, y) is under its roof: a box
  // set back from the roads, flat or with a ridge along its longer side.
  [[nodiscard]] Roof roof(double x, double y) const {
    const auto bx = static_cast<std::int64_t>(std::floor(x / kBlock));
    const auto by = static_cast<std::int64_t>(std::floor(y / kBlock));
    if (block(bx, by) != Block::built) return {};
    const double x0 = double(bx) * kBlock, y0 = double(by) * kBlock;
    const double lox = x0 + 10.0 + 12.0 * hash01(seed_, bx, by, 2);
    const double hix = x0 + kBlock - 10.0 - 12.0 * hash01(seed_, bx, by, 3);
    const double loy = y0 + 10.0 + 12.0 * hash01(seed_, bx, by, 4);
    const double hiy = y0 + kBlock - 10.0 - 12.0 * hash01(seed_, bx, by, 5);
    if (x < lox || x > hix || y < loy || y > hiy) return {};
    const double h = hash01(seed_, bx, by, 6);
    const double eaves = ground(x0 + 0.5 * kBlock, y0 + 0.5 * kBlock) + 6.0 + 40.0 * h * h;
    Roof r{true, eaves, static_cast<int>(4.0 * hash01(seed_, bx, by, 7))};
    if (hash01(seed_, bx, by, 8) < 0.5) {  // a ridge roof, pitch 1:2
      const bool along_x = hix - lox > hiy - loy;
      const double across = along_x ? std::min(y - loy, hiy - y) : std::min(x - lox, hix - x);
      r.z += 0.5 * across;
    }
    return r;
  }

  struct Crown {
    bool hit = false;
    double top = 0.0, bottom = 0.0;  // of the crown above (x, y)
    std::uint64_t id = 0;
  };
  // The highest crown over (x, y): trees stand on tree sites in wooded
  // blocks (most sites) and open ones (a few), never on a road; a crown is a
  // sphere of 2-5 m under its tree's top, 8-22 m above the ground.
  [[nodiscard]] Crown crown(double x, double y) const {
    Crown best;
    const auto sx = static_cast<std::int64_t>(std::floor(x / kSite));
    const auto sy = static_cast<std::int64_t>(std::floor(y / kSite));
    for (std::int64_t j = sy - 1; j <= sy + 1; ++j) {
      for (std::int64_t i = sx - 1; i <= sx + 1; ++i) {
        const double tx = (double(i) + 0.15 + 0.7 * hash01(seed_, i, j, 10)) * kSite;
        const double ty = (double(j) + 0.15 + 0.7 * hash01(seed_, i, j, 11)) * kSite;
        const double r = 2.0 + 3.0 * hash01(seed_, i, j, 12);
        const double d2 = (x - tx) * (x - tx) + (y - ty) * (y - ty);
        if (d2 >= r * r) continue;
        const auto bx = static_cast<std::int64_t>(std::floor(tx / kBlock));
        const auto by = static_cast<std::int64_t>(std::floor(ty / kBlock));
        const Block b = block(bx, by);
        const double chance = b == Block::wooded ? 0.85 : b == Block::open ? 0.06 : 0.0;
        if (hash01(seed_, i, j, 13) >= chance || on_road(tx, ty)) continue;
        const double centre = ground(tx, ty) + 8.0 + 14.0 * hash01(seed_, i, j, 14) - r;
        const double top = centre + std::sqrt(r * r - d2);
        if (!best.hit || top > best.top) {
          best = {true, top, centre - 0.8 * (top - centre),
                  static_cast<std::uint64_t>(i) * 0x9e3779b97f4a7c15ull ^
                      static_cast<std::uint64_t>(j)};
        }
      }
    }
    return best;
  }

 private:
  std::uint64_t seed_;
  std::array<double, 5> phase_{};
};

glm::u8vec4 colour(double r, double g, double b) {
  auto c = [](double v) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
  };
  return {c(r), c(g), c(b), 255};
}

// The tile's points and their fields, appended a return at a time.
struct TileWriter {
  PointSet points;
  std::vector<float> intensity, return_number, returns, classification, scan_angle, source;
  std::vector<double> gps_time;

  void reserve(std::size_t n) {
    points.positions.reserve(n);
    points.colors.reserve(n);
    for (auto* v : {&intensity, &return_number, &returns, &classification, &scan_angle, &source})
      v->reserve(n);
    gps_time.reserve(n);
  }

  void add_attribute(std::string name, ValueType type, std::vector<float> values) {
    PointAttribute a;
    a.name = std::move(name);
    a.kind = attribute_kind_for(a.name);
    a.type = type;
    if (std::all_of(values.begin(), values.end(), [&](float v) { return v == values.front(); })) {
      a.constant = values.empty() ? 0.0 : double(values.front());
    } else {
      a.values = std::move(values);
    }
    points.attributes.push_back(std::move(a));
  }

  PointSet finish() {
    add_attribute("intensity", ValueType::u16, std::move(intensity));
    add_attribute("return_number", ValueType::u8, std::move(return_number));
    add_attribute("number_of_returns", ValueType::u8, std::move(returns));
    add_attribute("classification", ValueType::u8, std::move(classification));
    add_attribute("scan_angle", ValueType::i8, std::move(scan_angle));
    add_attribute("point_source_id", ValueType::u16, std::move(source));
    PointAttribute t;
    t.name = "gps_time";
    t.kind = AttributeKind::measure;
    t.type = ValueType::f64;
    t.wide = std::move(gps_time);
    points.attributes.push_back(std::move(t));
    return std::move(points);
  }
};

}  // namespace

std::string geotiff_keys_for_epsg(int code) {
  // GeoKeyDirectoryTag (GeoTIFF 1.0, 2.4): version 1.1.0, four keys, each
  // (id, location 0 = in place, count 1, value): a projected model, pixel is
  // area, the projected system, its unit the metre (9001).
  const std::uint16_t keys[] = {1,    1, 0, 4,   1024, 0, 1, 1,
                                1025, 0, 1, 1,   3072, 0, 1, static_cast<std::uint16_t>(code),
                                3076, 0, 1, 9001};
  std::string out;
  for (const std::uint16_t k : keys) {
    out.push_back(static_cast<char>(k & 0xff));
    out.push_back(static_cast<char>(k >> 8));
  }
  return out;
}

std::vector<SurveyTile> survey_tiles(const SurveyOptions& o) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(o.width) || !positive(o.height) || !positive(o.density) || !positive(o.tile))
    throw std::invalid_argument("the area, density and tile must be positive");
  const double total = std::round(o.density * o.width * o.height);
  if (total < 1.0 || total > 0x1.0p40) throw std::invalid_argument("between 1 and 2^40 points");
  const auto columns = static_cast<int>(std::ceil(o.width / o.tile));
  const auto rows = static_cast<int>(std::ceil(o.height / o.tile));
  std::vector<SurveyTile> tiles;
  tiles.reserve(static_cast<std::size_t>(columns) * static_cast<std::size_t>(rows));
  // Points by area, rounded on the running sum so that they add up exactly.
  double area_before = 0.0;
  const double area = o.width * o.height;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      SurveyTile t;
      t.column = c, t.row = r;
      t.lo = {c * o.tile, r * o.tile};
      t.hi = {std::min(o.width, (c + 1) * o.tile), std::min(o.height, (r + 1) * o.tile)};
      const double after = area_before + (t.hi.x - t.lo.x) * (t.hi.y - t.lo.y);
      t.points = static_cast<std::uint64_t>(std::round(total * after / area) -
                                            std::round(total * area_before / area));
      area_before = after;
      char name[64];
      std::snprintf(name, sizeof name, "tile_%.0f_%.0f.las", std::floor(o.origin.x + t.lo.x),
                    std::floor(o.origin.y + t.lo.y));
      t.file_name = name;
      tiles.push_back(std::move(t));
    }
  }
  return tiles;
}

PointSet generate_survey_tile(const SurveyOptions& o, const SurveyTile& tile) {
  const World world(o.seed);
  Random random(
      splitmix64(o.seed ^ splitmix64(std::uint64_t(tile.row) << 32 | std::uint32_t(tile.column))));
  const auto n = static_cast<std::size_t>(tile.points);
  TileWriter w;
  w.reserve(n);
  PointSet& ps = w.points;
  // Positions relative to the tile's corner in whole metres, on the file's
  // millimetre grid (floats of a few hundred metres hold it).
  ps.frame.origin = glm::round(o.origin + glm::dvec3(tile.lo, 0.0));
  ps.frame.resolution = glm::dvec3(0.001);
  ps.frame.grid_offset = glm::round(o.origin);
  ps.frame.z_up = true;
  ps.frame.crs_records.geo_keys = geotiff_keys_for_epsg(o.epsg);
  ps.frame.crs = "EPSG:" + std::to_string(o.epsg) + " (projected)";
  ps.adjusted_gps_time = true;
  const glm::dvec3 local_origin = ps.frame.origin - o.origin;  // the corner, in area metres
  const auto mm = [](double v) { return std::round(v * 1000.0) / 1000.0; };

  // A later return of a pulse lands a little off its first, within the tile.
  const auto jitter = [&](double v, double sigma, double lo, double hi) {
    return std::clamp(mm(v + sigma * random.normal()), lo, hi - 0.001);
  };
  std::size_t pulse = 0;
  while (w.points.positions.size() < n) {
    const double x =
        std::min(mm(tile.lo.x + random.next() * (tile.hi.x - tile.lo.x)), tile.hi.x - 0.001);
    const double y =
        std::min(mm(tile.lo.y + random.next() * (tile.hi.y - tile.lo.y)), tile.hi.y - 0.001);
    const auto line = static_cast<int>(std::floor(x / kLine));
    const double line_x = (line + 0.5) * kLine;
    const double along = line % 2 == 0 ? y : o.height - y;
    const double time = 3.2e8 + 1200.0 * line + along / kSpeed + 1e-6 * double(pulse++ % 1000);
    const float angle =
        static_cast<float>(std::round(std::atan((x - line_x) / kAltitude) * 57.29577951308232));
    const auto add = [&](double px, double py, double z, float cls, float k, float of,
                         double strength, glm::u8vec4 rgb) {
      ps.positions.emplace_back(float(px - local_origin.x), float(py - local_origin.y),
                                float(mm(z + o.origin.z) - local_origin.z - o.origin.z));
      ps.colors.push_back(rgb);
      w.intensity.push_back(float(std::clamp(std::round(strength), 0.0, 65535.0)));
      w.return_number.push_back(k);
      w.returns.push_back(of);
      w.classification.push_back(cls);
      w.scan_angle.push_back(angle);
      w.source.push_back(float(line + 1));
      w.gps_time.push_back(time);
    };
    const double shade = 0.85 + 0.15 * random.next();
    if (const World::Roof roof = world.roof(x, y); roof.hit) {
      static constexpr double kRoofs[4][3] = {
          {0.62, 0.28, 0.22}, {0.45, 0.45, 0.47}, {0.25, 0.26, 0.30}, {0.70, 0.66, 0.58}};
      const double* c = kRoofs[roof.palette];
      add(x, y, roof.z + 0.02 * random.normal(), kBuilding, 1, 1, 1800.0 + 600.0 * random.next(),
          colour(c[0] * shade, c[1] * shade, c[2] * shade));
      continue;
    }
    const double g = world.ground(x, y) + 0.02 * random.normal();
    const bool road = World::on_road(x, y);
    const glm::u8vec4 ground_colour =
        road ? colour(0.36 * shade, 0.36 * shade, 0.37 * shade)
             : colour((0.42 + 0.1 * std::sin(x / 23.0)) * shade, 0.52 * shade, 0.28 * shade);
    const float ground_class = road ? kRoadSurface : kGround;
    const double ground_strength =
        road ? 400.0 + 300.0 * random.next() : 900.0 + 600.0 * random.next();
    if (const World::Crown crown = world.crown(x, y); crown.hit) {
      // One return from the crown's top, and as the pulse goes on through
      // gaps in the leaves, one from inside it and one from the ground.
      const double u = random.next();
      const std::size_t left = n - ps.positions.size();
      const int count = static_cast<int>(std::min<std::size_t>(left, u < 0.3    ? 1
                                                                     : u < 0.65 ? 2
                                                                                : 3));
      const double tint = 0.75 + 0.25 * double(crown.id % 7) / 6.0;
      const glm::u8vec4 leaves = colour(0.18 * shade * tint, 0.36 * shade * tint, 0.14 * shade);
      add(x, y, crown.top - 0.3 * random.next(), kVegetation, 1, float(count),
          (300.0 + 600.0 * random.next()), leaves);
      if (count == 3) {
        add(jitter(x, 0.01, tile.lo.x, tile.hi.x), jitter(y, 0.01, tile.lo.y, tile.hi.y),
            crown.bottom + (crown.top - crown.bottom) * random.next(), kVegetation, 2, 3,
            200.0 + 300.0 * random.next(), leaves);
      }
      if (count >= 2) {
        add(jitter(x, 0.02, tile.lo.x, tile.hi.x), jitter(y, 0.02, tile.lo.y, tile.hi.y), g,
            ground_class, float(count), float(count), 0.4 * ground_strength, ground_colour);
      }
      continue;
    }
    add(x, y, g, ground_class, 1, 1, ground_strength, ground_colour);
  }
  return w.finish();
}

}  // namespace treecut::tools
