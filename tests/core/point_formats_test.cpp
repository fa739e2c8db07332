// The point file readers besides PLY (ply_test.cpp): text clouds
// (treecut/text_cloud.hpp: XYZ, PTS, CSV) and, above all, LAS import and
// export (treecut/las.hpp) on files built here, byte by byte,
// from the ASPRS LAS 1.4 R15 tables: every point format, the 1.4 counts, the
// coordinate system records, 8- and 16-bit colours, map coordinates kept to
// the millimetre, round trips exact to the scale, and the malformed files
// (every truncation of the header, counts past the file, absurd scales and
// offsets, a format and a record length that disagree, LAZ) refused with
// one line.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/pcd.hpp"
#include "treecut/text_cloud.hpp"

namespace {

using treecut::InputError;
using treecut::LasLoadReport;
using treecut::load_las_from_memory;
using treecut::PointSet;

template <class T>
void put(std::string& out, T v) {
  static_assert(std::endian::native == std::endian::little);
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
template <class T>
void poke(std::string& out, std::size_t at, T v) {
  std::memcpy(out.data() + at, &v, sizeof v);
}

constexpr std::uint32_t kBase[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
constexpr std::uint32_t kRgb[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

struct Point {
  std::int32_t x, y, z;
  std::uint16_t r = 0, g = 0, b = 0;
};

struct Vlr {
  std::string user;
  std::uint16_t id;
  std::string payload;
};

// A LAS file of version 1.MINOR, point format FORMAT with EXTRA bytes after
// each record, the given scale and offset, VLRS and the points.
std::string las_file(int minor, int format, const std::vector<Point>& points, double scale = 0.01,
                     double offset = 0.0, std::uint32_t extra = 0,
                     const std::vector<Vlr>& vlrs = {}) {
  const std::size_t header = minor >= 4 ? 375 : minor == 3 ? 235 : 227;
  std::string h;
  h += "LASF";
  put<std::uint16_t>(h, 0);
  put<std::uint16_t>(h, 0);
  h.append(16, '\0');
  h.push_back(1);
  h.push_back(static_cast<char>(minor));
  std::string sys = "test system";
  sys.resize(32, '\0');
  h += sys;
  h.append(32, '\0');
  put<std::uint16_t>(h, 1);
  put<std::uint16_t>(h, 2026);
  put<std::uint16_t>(h, static_cast<std::uint16_t>(header));
  std::size_t vlr_bytes = 0;
  for (const Vlr& v : vlrs) vlr_bytes += 54 + v.payload.size();
  put<std::uint32_t>(h, static_cast<std::uint32_t>(header + vlr_bytes));
  put<std::uint32_t>(h, static_cast<std::uint32_t>(vlrs.size()));
  h.push_back(static_cast<char>(format));
  const std::uint32_t length = kBase[format] + extra;
  put<std::uint16_t>(h, static_cast<std::uint16_t>(length));
  put<std::uint32_t>(h, format >= 6 ? 0u : static_cast<std::uint32_t>(points.size()));
  for (int i = 0; i < 5; ++i) put<std::uint32_t>(h, 0);
  for (int a = 0; a < 3; ++a) put<double>(h, scale);
  for (int a = 0; a < 3; ++a) put<double>(h, offset);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const Point& p : points) {
    const std::int32_t c[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], c[a] * scale + offset);
      hi[a] = std::max(hi[a], c[a] * scale + offset);
    }
  }
  for (int a = 0; a < 3; ++a) {
    put<double>(h, points.empty() ? 0.0 : hi[a]);
    put<double>(h, points.empty() ? 0.0 : lo[a]);
  }
  if (minor >= 3) put<std::uint64_t>(h, 0);  // waveform data start
  if (minor >= 4) {
    put<std::uint64_t>(h, 0);  // first EVLR
    put<std::uint32_t>(h, 0);  // EVLRs
    put<std::uint64_t>(h, points.size());
    for (int i = 0; i < 15; ++i) put<std::uint64_t>(h, 0);
  }
  EXPECT_EQ(h.size(), header);
  for (const Vlr& v : vlrs) {
    put<std::uint16_t>(h, 0);
    std::string user = v.user;
    user.resize(16, '\0');
    h += user;
    put<std::uint16_t>(h, v.id);
    put<std::uint16_t>(h, static_cast<std::uint16_t>(v.payload.size()));
    h.append(32, '\0');
    h += v.payload;
  }
  for (const Point& p : points) {
    std::string r(length, '\0');
    poke(r, 0, p.x), poke(r, 4, p.y), poke(r, 8, p.z);
    if (kRgb[format] != 0) {
      poke(r, kRgb[format], p.r), poke(r, kRgb[format] + 2, p.g), poke(r, kRgb[format] + 4, p.b);
    }
    h += r;
  }
  return h;
}

std::string error_of(const std::string& bytes) {
  try {
    (void)load_las_from_memory(bytes, "mem.las");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(loaded)";
}

const std::vector<Point> kThree = {
    {100, 200, 300, 65535, 0, 0}, {-100, 0, 50, 0, 65535, 0}, {0, -200, 0, 0, 0, 65535}};

// Point I in the file's coordinates, as the floats give it.
glm::dvec3 file_position(const PointSet& p, std::size_t i) {
  return p.frame.origin + glm::dvec3(p.positions[i]);
}

// ... and as the reader kept it where the floats do not give it back.
glm::dvec3 exact_position(const PointSet& p, std::size_t i) {
  return p.exact_positions.empty() ? file_position(p, i) : p.exact_positions[i];
}

TEST(LasLoad, EveryPointFormatGivesItsPointsAndColours) {
  for (int format = 0; format <= 10; ++format) {
    const int minor = format >= 6 ? 4 : format >= 4 ? 3 : 2;
    std::vector<std::string> warnings;
    LasLoadReport report;
    const PointSet p =
        load_las_from_memory(las_file(minor, format, kThree, 0.01, 1000.0, 3), "mem.las", &report,
                             [&](const std::string& w) { warnings.push_back(w); });
    ASSERT_EQ(p.size(), 3u) << format;
    EXPECT_EQ(report.info.point_format, format);
    EXPECT_EQ(report.info.record_length, kBase[format] + 3);
    for (std::size_t i = 0; i < 3; ++i) {
      const glm::dvec3 q = file_position(p, i);
      EXPECT_NEAR(q.x, kThree[i].x * 0.01 + 1000.0, 1e-4) << format;
      EXPECT_NEAR(q.y, kThree[i].y * 0.01 + 1000.0, 1e-4) << format;
      EXPECT_NEAR(q.z, kThree[i].z * 0.01 + 1000.0, 1e-4) << format;
    }
    if (kRgb[format] != 0) {
      ASSERT_TRUE(p.has_colors()) << format;
      EXPECT_EQ(p.colors[0], glm::u8vec4(255, 0, 0, 255));
      EXPECT_EQ(p.colors[2], glm::u8vec4(0, 0, 255, 255));
    } else {
      EXPECT_FALSE(p.has_colors()) << format;
    }
    const bool waveform = format == 4 || format == 5 || format >= 9;
    EXPECT_EQ(report.info.waveform, waveform);
    bool said_waveform = false, said_not_kept = false;
    for (const std::string& w : warnings) {
      said_waveform = said_waveform || w.find("waveform") != std::string::npos;
      said_not_kept = said_not_kept || w.find("not kept") != std::string::npos;
      EXPECT_EQ(w.find('\n'), std::string::npos);
    }
    EXPECT_EQ(said_waveform, waveform) << format;
    // Issue 43: a field with one value at every point is kept, once.
    EXPECT_FALSE(said_not_kept) << format;
    ASSERT_FALSE(p.attributes.empty());
    EXPECT_EQ(p.attributes[0].name, "intensity");
    EXPECT_TRUE(p.attributes[0].is_constant()) << format;
    EXPECT_EQ(p.attributes[0].value(2), 0.0) << format;
  }
}

TEST(LasLoad, EightBitColoursAreTakenAsTheyAre) {
  const std::vector<Point> p8 = {{0, 0, 0, 200, 100, 50}, {1, 1, 1, 255, 0, 7}};
  const PointSet p = load_las_from_memory(las_file(2, 2, p8), "mem.las");
  EXPECT_EQ(p.colors[0], glm::u8vec4(200, 100, 50, 255));
  EXPECT_EQ(p.colors[1], glm::u8vec4(255, 0, 7, 255));
}

TEST(LasLoad, MapCoordinatesKeepTheirMillimetres) {
  // A 1 cm grid at x = 500 km, y = 5,000 km (UTM-like metres): as floats of
  // the absolute coordinates its points would fall on 0.5 m steps.
  std::vector<Point> grid;
  for (int i = 0; i < 50; ++i) grid.push_back({i * 10, i * 10, 0});
  const PointSet p = load_las_from_memory(las_file(2, 0, grid, 0.001, 0.0, 0), "mem.las");
  std::string bytes = las_file(2, 0, grid, 0.001, 0.0);
  // The same grid at map coordinates: offset 500000 / 5000000.
  for (int a = 0; a < 2; ++a) poke<double>(bytes, 155 + 8 * a, a == 0 ? 500000.0 : 5000000.0);
  for (int a = 0; a < 2; ++a) {
    const double o = a == 0 ? 500000.0 : 5000000.0;
    poke<double>(bytes, 179 + 16 * a, o + 0.49);
    poke<double>(bytes, 187 + 16 * a, o);
  }
  const PointSet m = load_las_from_memory(bytes, "mem.las");
  ASSERT_EQ(m.size(), grid.size());
  EXPECT_GT(m.frame.origin.y, 4.9e6) << "the origin is near the points";
  for (std::size_t i = 1; i < m.size(); ++i) {
    const glm::dvec3 step = file_position(m, i) - file_position(m, i - 1);
    EXPECT_NEAR(step.x, 0.01, 1e-5) << i;
    EXPECT_NEAR(step.y, 0.01, 1e-5) << i;
    // Relative to the origin the positions are those of the grid at 0.
    EXPECT_NEAR(m.positions[i].x - m.positions[0].x, p.positions[i].x - p.positions[0].x, 1e-5);
  }
}

TEST(LasLoad, Version14CountsTheExtendedWay) {
  std::string bytes = las_file(4, 6, kThree);
  EXPECT_EQ(load_las_from_memory(bytes, "mem.las").size(), 3u);
  poke<std::uint32_t>(bytes, 107, 2);  // a legacy count that disagrees
  EXPECT_EQ(error_of(bytes), "mem.las: the legacy point count 2 and the point count 3 disagree");
  poke<std::uint32_t>(bytes, 107, 3);  // one that agrees
  EXPECT_EQ(load_las_from_memory(bytes, "mem.las").size(), 3u);
}

TEST(LasLoad, CoordinateSystemRecordsAreRead) {
  const std::string wkt = "PROJCS[\"WGS 84 / UTM zone 33N\"]";
  LasLoadReport r;
  (void)load_las_from_memory(
      las_file(4, 6, kThree, 0.01, 0.0, 0, {{"LASF_Projection", 2112, wkt + std::string(1, '\0')}}),
      "mem.las", &r);
  EXPECT_EQ(r.info.crs, "WKT: " + wkt);
  const PointSet with_crs = load_las_from_memory(
      las_file(4, 6, kThree, 0.01, 0.0, 0, {{"LASF_Projection", 2112, wkt + std::string(1, '\0')}}),
      "mem.las");
  EXPECT_EQ(with_crs.frame.crs, "WKT: " + wkt) << "the frame carries it to the hierarchy";
  EXPECT_TRUE(with_crs.frame.z_up);
  // GeoKeyDirectory: version 1.1.0, 1 key, ProjectedCSTypeGeoKey = 32633.
  std::string keys;
  for (const std::uint16_t v : {1, 1, 0, 1, 3072, 0, 1, 32633}) put<std::uint16_t>(keys, v);
  (void)load_las_from_memory(
      las_file(2, 0, kThree, 0.01, 0.0, 0, {{"LASF_Projection", 34735, keys}}), "mem.las", &r);
  EXPECT_EQ(r.info.crs, "EPSG:32633 (projected)");
  // Issue 43, item 3: the projected key wins over the geographic one (the
  // datum under it), wherever it stands; 32767 is user-defined.
  keys.clear();
  for (const std::uint16_t v : {1, 1, 0, 3, 1024, 0, 1, 1, 2048, 0, 1, 4269, 3072, 0, 1, 3597})
    put<std::uint16_t>(keys, v);
  (void)load_las_from_memory(
      las_file(2, 0, kThree, 0.01, 0.0, 0, {{"LASF_Projection", 34735, keys}}), "mem.las", &r);
  EXPECT_EQ(r.info.crs, "EPSG:3597 (projected)");
  keys.clear();
  for (const std::uint16_t v : {1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32767})
    put<std::uint16_t>(keys, v);
  (void)load_las_from_memory(
      las_file(2, 0, kThree, 0.01, 0.0, 0, {{"LASF_Projection", 34735, keys}}), "mem.las", &r);
  EXPECT_EQ(r.info.crs, "user-defined (projected)");
  keys.clear();
  for (const std::uint16_t v : {1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326})
    put<std::uint16_t>(keys, v);
  (void)load_las_from_memory(
      las_file(2, 0, kThree, 0.01, 0.0, 0, {{"LASF_Projection", 34735, keys}}), "mem.las", &r);
  EXPECT_EQ(r.info.crs, "EPSG:4326 (geographic)");
  // Extra bytes: two named fields.
  std::string extra(384, '\0');
  std::memcpy(extra.data() + 4, "reflectance", 11);
  std::memcpy(extra.data() + 192 + 4, "deviation", 9);
  std::vector<std::string> warnings;
  (void)load_las_from_memory(las_file(4, 6, kThree, 0.01, 0.0, 4, {{"LASF_Spec", 4, extra}}),
                             "mem.las", &r, [&](const std::string& w) { warnings.push_back(w); });
  ASSERT_EQ(r.info.extra_bytes.size(), 2u);
  EXPECT_EQ(r.info.extra_bytes[0].name, "reflectance");
  EXPECT_EQ(r.info.extra_bytes[1].name, "deviation");
  bool named = false;
  for (const std::string& w : warnings) named = named || w.find("reflectance") != std::string::npos;
  EXPECT_TRUE(named);
}

TEST(LasLoad, EveryTruncationOfTheHeaderIsOneLine) {
  for (const int minor : {2, 3, 4}) {
    const std::string full = las_file(minor, minor == 4 ? 7 : 3, kThree);
    for (std::size_t cut = 0; cut < full.size(); ++cut) {
      const std::string e = error_of(full.substr(0, cut));
      EXPECT_EQ(e.rfind("mem.las: ", 0), 0u) << cut << ": " << e;
      EXPECT_EQ(e.find('\n'), std::string::npos) << cut;
    }
  }
  EXPECT_EQ(error_of("LASF"),
            "mem.las: the header is cut off: 4 bytes, a LAS header has at least 227");
  EXPECT_EQ(error_of(las_file(2, 0, kThree).substr(0, 227 + 30)),
            "mem.las: 3 points of 20 bytes declared from offset 227, the file holds 1");
}

TEST(LasLoad, AbsurdHeadersAreRefusedBeforeAnythingIsSized) {
  const std::string ok = las_file(2, 2, kThree);
  auto with = [&](std::size_t at, auto v) {
    std::string b = ok;
    poke(b, at, v);
    return error_of(b);
  };
  EXPECT_EQ(with(131, 0.0), "mem.las: X scale factor 0 (it must be positive and finite)");
  EXPECT_EQ(with(139, -0.01), "mem.las: Y scale factor -0.01 (it must be positive and finite)");
  EXPECT_EQ(with(147, std::nan("")),
            "mem.las: Z scale factor nan (it must be positive and finite)");
  EXPECT_EQ(with(155, std::numeric_limits<double>::infinity()),
            "mem.las: X offset inf is not finite");
  EXPECT_EQ(with(131, 1e300),
            "mem.las: X scale factor 1.0000000000000001e+300 and offset 0 reach coordinates beyond "
            "1e18");
  EXPECT_EQ(with(107, std::uint32_t{4000000000u}),
            "mem.las: 4000000000 points of 26 bytes declared from offset 227, the file holds 3");
  // A record length shorter than the format's.
  EXPECT_EQ(with(105, std::uint16_t{20}),
            "mem.las: point data format 2 has records of 26 bytes; the header says 20");
  EXPECT_EQ(with(104, std::uint8_t{11}),
            "mem.las: point data format 11 is not defined (0 to 10 are)");
  EXPECT_EQ(with(25, std::uint8_t{5}), "mem.las: LAS version 1.5 is not read (1.0 to 1.4 are)");
  EXPECT_EQ(with(94, std::uint16_t{100}),
            "mem.las: header size 100 is less than the 227 bytes of a LAS 1.2 header");
  EXPECT_EQ(with(96, std::uint32_t{1u << 30}),
            "mem.las: the point data offset 1073741824 is not between the header's end (227) and "
            "the end of the file (305)");
  EXPECT_EQ(with(100, std::uint32_t{1}),
            "mem.las: variable length record 1 of 1 runs past the point data offset 227");
  EXPECT_EQ(error_of("LASX" + ok.substr(4)), "mem.las: not a LAS file (no LASF signature)");
}

TEST(LasLoad, LazIsNamedWithTheWayOut) {
  std::string laz = las_file(2, 2, kThree);
  laz[104] = static_cast<char>(2 | 0x80);
  const std::string e = error_of(laz);
  EXPECT_NE(e.find("a LAZ (compressed LAS) file"), std::string::npos) << e;
  EXPECT_NE(e.find("decompress it to LAS first"), std::string::npos) << e;
}

TEST(LasLoad, RandomCorruptionIsRefusedOrRead) {
  const std::string ok =
      las_file(4, 8, kThree, 0.01, 0.0, 2, {{"LASF_Projection", 2112, std::string("PROJCS[]", 9)}});
  std::mt19937 rng(7);
  for (int i = 0; i < 3000; ++i) {
    std::string b = ok;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) b[rng() % b.size()] = static_cast<char>(rng());
    try {
      const PointSet p = load_las_from_memory(b, "mem.las");
      EXPECT_LE(p.size(), 3u);
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
}

TEST(LasSave, RoundTripsAreExactToTheScale) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-500.0f, 500.0f);
  PointSet p;
  p.frame.origin = glm::dvec3(500000.0, 5000000.0, 120.0);
  for (int i = 0; i < 2000; ++i) {
    p.positions.push_back({u(rng), u(rng), 0.1f * u(rng)});
    p.colors.push_back({static_cast<std::uint8_t>(rng()), static_cast<std::uint8_t>(rng()),
                        static_cast<std::uint8_t>(rng()), 255});
  }
  const auto dir = treecut::test::scratch_dir("las_save");
  const auto a = dir / "a.las", b = dir / "b.las";
  treecut::save_las(a, p);
  LasLoadReport r;
  const PointSet q = treecut::load_las(a, &r);
  ASSERT_EQ(q.size(), p.size());
  EXPECT_EQ(r.info.point_format, 2);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const glm::dvec3 d = file_position(q, i) - file_position(p, i);
    // Within half a step of the scale (0.5 mm), plus the float positions'
    // own rounding near 500 m from the origin (30 um).
    EXPECT_LE(std::abs(d.x), 0.0005 + 3e-5) << i;
    EXPECT_LE(std::abs(d.y), 0.0005 + 3e-5) << i;
    EXPECT_EQ(q.colors[i], p.colors[i]) << i;
  }
  // Written again from what was read: the same integers, the same file.
  treecut::save_las(b, q);
  auto bytes = [](const std::filesystem::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(bytes(a), bytes(b));
}

// A record's fields at their offsets (LAS 1.4 R15, tables 7 and 12).
TEST(LasLoad, EveryFieldIsKeptAsANamedAttribute) {
  std::vector<std::string> warnings;
  auto warn = [&](const std::string& w) { warnings.push_back(w); };
  auto values = [](const PointSet& p, const std::string& name) {
    for (const treecut::PointAttribute& a : p.attributes) {
      if (a.name == name) {
        std::vector<double> v;
        for (std::size_t i = 0; i < p.size(); ++i) v.push_back(a.value(i));
        return v;
      }
    }
    return std::vector<double>{};
  };
  // Legacy format 1: intensity, returns and flags in bytes, GPS time.
  std::string legacy = las_file(2, 1, kThree);
  const std::size_t at = legacy.size() - 3 * 28;
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t r = at + i * 28;
    poke<std::uint16_t>(legacy, r + 12, static_cast<std::uint16_t>(100 * (i + 1)));
    legacy[r + 14] = static_cast<char>((i + 1) | (3 << 3));                      // return i+1 of 3
    legacy[r + 15] = static_cast<char>((i == 1 ? 6 : 2) | (i == 2 ? 0x80 : 0));  // withheld
    legacy[r + 16] = static_cast<char>(-10 + 10 * static_cast<int>(i));
    poke<std::uint16_t>(legacy, r + 18, 7);  // point source id: the same everywhere
    poke<double>(legacy, r + 20, 3.0e8 + 0.25 * double(i));
  }
  const PointSet a = load_las_from_memory(legacy, "legacy.las", nullptr, warn);
  EXPECT_EQ(values(a, "intensity"), (std::vector<double>{100, 200, 300}));
  EXPECT_EQ(values(a, "return_number"), (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(values(a, "classification"), (std::vector<double>{2, 6, 2}));
  EXPECT_EQ(values(a, "classification_flags"), (std::vector<double>{0, 0, 4}));
  EXPECT_EQ(values(a, "scan_angle"), (std::vector<double>{-10, 0, 10}));
  // A GPS time of 3e8 s keeps its quarter seconds (float relative to an offset).
  EXPECT_EQ(values(a, "gps_time"), (std::vector<double>{3.0e8, 3.0e8 + 0.25, 3.0e8 + 0.5}));
  // Issue 43, item 1: one value everywhere is kept, stored once.
  EXPECT_EQ(values(a, "number_of_returns"), (std::vector<double>{3, 3, 3}));
  EXPECT_EQ(values(a, "point_source_id"), (std::vector<double>{7, 7, 7}));
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  for (const treecut::PointAttribute& x : a.attributes) {
    EXPECT_EQ(x.kind, x.name == "intensity" || x.name == "scan_angle" || x.name == "gps_time"
                          ? treecut::AttributeKind::measure
                          : treecut::AttributeKind::category)
        << x.name;
  }

  // Format 8 (1.4): the class in its own byte, scan angle in 0.006 degree
  // steps, NIR; an extra-bytes float with a scale and a no-data value.
  std::string extra(192, '\0');
  extra[2] = 4;      // short
  extra[3] = 1 | 8;  // no_data, scale
  std::memcpy(extra.data() + 4, "height_above_ground", 19);
  poke<std::int64_t>(extra, 40, -1);  // no_data
  poke<double>(extra, 112, 0.01);     // scale
  std::string ext = las_file(4, 8, kThree, 0.01, 0.0, 2, {{"LASF_Spec", 4, extra}});
  const std::size_t at8 = ext.size() - 3 * 40;
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t r = at8 + i * 40;
    ext[r + 16] = static_cast<char>(i == 0 ? 9 : 17);  // water, bridge deck
    poke<std::int16_t>(ext, r + 18, static_cast<std::int16_t>(1000 * static_cast<int>(i)));
    poke<std::uint16_t>(ext, r + 36, static_cast<std::uint16_t>(50 + i));  // NIR
    poke<std::int16_t>(ext, r + 38, static_cast<std::int16_t>(i == 2 ? -1 : 150 * (i + 1)));
  }
  warnings.clear();
  const PointSet b = load_las_from_memory(ext, "ext.las", nullptr, warn);
  EXPECT_EQ(values(b, "classification"), (std::vector<double>{9, 17, 17}));
  const std::vector<double> angle = values(b, "scan_angle");
  ASSERT_EQ(angle.size(), 3u);
  EXPECT_NEAR(angle[2], 12.0, 1e-4);
  EXPECT_EQ(values(b, "nir"), (std::vector<double>{50, 51, 52}));
  const std::vector<double> hag = values(b, "height_above_ground");
  ASSERT_EQ(hag.size(), 3u);
  EXPECT_NEAR(hag[0], 1.5, 1e-6);
  EXPECT_NEAR(hag[1], 3.0, 1e-6);
  EXPECT_TRUE(std::isnan(hag[2])) << "the no-data value is no value";
}

TEST(LasSave, AttributesRoundTrip) {
  PointSet p;
  p.frame.origin = glm::dvec3(600000.0, 4000000.0, 50.0);
  treecut::PointAttribute intensity{
      .name = "intensity", .kind = treecut::AttributeKind::measure, .offset = 0.0};
  treecut::PointAttribute cls{
      .name = "classification", .kind = treecut::AttributeKind::category, .offset = 0.0};
  treecut::PointAttribute time{
      .name = "gps_time", .kind = treecut::AttributeKind::measure, .offset = 2.0e8};
  treecut::PointAttribute reflectance{
      .name = "reflectance", .kind = treecut::AttributeKind::measure, .offset = 0.0};
  for (int i = 0; i < 500; ++i) {
    p.positions.push_back({0.1f * float(i), 0.2f * float(i % 7), 0.0f});
    intensity.values.push_back(float(i * 13 % 4000));
    cls.values.push_back(float(i % 3 == 0 ? 2 : 6));
    time.values.push_back(0.001f * float(i));
    reflectance.values.push_back(-0.5f + 0.003f * float(i));
  }
  p.attributes = {intensity, cls, time, reflectance};
  const auto dir = treecut::test::scratch_dir("las_attributes");
  treecut::save_las(dir / "a.las", p);
  LasLoadReport r;
  const PointSet q = treecut::load_las(dir / "a.las", &r);
  EXPECT_EQ(r.info.point_format, 1) << "gps_time asks for format 1";
  auto find = [&](const std::string& name) -> const treecut::PointAttribute* {
    for (const treecut::PointAttribute& a : q.attributes) {
      if (a.name == name) return &a;
    }
    return nullptr;
  };
  for (const treecut::PointAttribute& a : p.attributes) {
    const treecut::PointAttribute* b = find(a.name);
    ASSERT_NE(b, nullptr) << a.name;
    for (std::size_t i = 0; i < p.size(); ++i) {
      EXPECT_NEAR(b->value(i), a.value(i), 1e-6) << a.name;
    }
  }
}

TEST(LasSave, RefusesWhatLasCannotHold) {
  PointSet p;
  p.positions = {{0, 0, 0}, {1e9f, 0, 0}};
  const auto dir = treecut::test::scratch_dir("las_refuse");
  treecut::LasWriteOptions o;
  o.scale = 0.001;
  // 1e12 steps of a millimetre: the message names the file, not a function.
  try {
    treecut::save_las(dir / "x.las", p, o);
    ADD_FAILURE() << "written";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir / "x.las").string() + ": the points span", 0), 0u)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "x.las"));
  // Without a scale the writer picks one that reaches them.
  treecut::save_las(dir / "x.las", p);
  EXPECT_EQ(treecut::load_las(dir / "x.las").size(), 2u);
  o.scale = -1.0;
  EXPECT_THROW(treecut::save_las(dir / "y.las", PointSet{}, o), std::invalid_argument);
}

// ---- Text clouds ----------------------------------------------------------

std::string text_error_of(const std::string& text) {
  try {
    (void)treecut::load_text_cloud_from_memory(text, "mem.xyz");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(loaded)";
}

TEST(TextCloud, XyzPtsAndCsvAreRecognizedAndRead) {
  using treecut::looks_like_text_cloud;
  EXPECT_TRUE(looks_like_text_cloud("1 2 3\n4 5 6\n"));
  EXPECT_TRUE(looks_like_text_cloud("2\n1 2 3 0 10 20 30\n4 5 6 0 40 50 60\n"));
  EXPECT_TRUE(looks_like_text_cloud("X,Y,Z,Intensity\n1,2,3,9\n"));
  EXPECT_TRUE(looks_like_text_cloud("# exported\n1;2;3\n"));
  // Any text is the text reader's when no other signature claims it (issue
  // 43, item 17): it says what is wrong (the caller tries PLY, LAS and PCD
  // first); binary bytes are not text.
  EXPECT_TRUE(looks_like_text_cloud("hello world\n"));
  EXPECT_TRUE(looks_like_text_cloud("\xEF\xBB\xBFx,y,z\n1,2,3\n")) << "a byte order mark";
  EXPECT_TRUE(looks_like_text_cloud("h\xC3\xB6he,x,y,z\n1,2,3,4\n")) << "UTF-8";
  EXPECT_FALSE(looks_like_text_cloud(std::string("LASF\0\0", 6)));
  EXPECT_FALSE(looks_like_text_cloud("\x89PNG\r\n\x1a\n"));
  EXPECT_FALSE(looks_like_text_cloud("h\xF6h\xE9\n")) << "Latin-1 is not UTF-8";
  EXPECT_TRUE(looks_like_text_cloud("1 2 3\n4 5\x00\x36\n"))
      << "one stray byte: the reader names it";
  EXPECT_FALSE(looks_like_text_cloud(" \n\n"));

  // XYZ RGB at map coordinates: millimetres kept.
  const PointSet a = treecut::load_text_cloud_from_memory(
      "500000.001 5000000.002 100.5 255 0 10\n500000.011 5000000.012 100.5 0 255 20\n", "a.xyz");
  ASSERT_EQ(a.size(), 2u);
  EXPECT_NEAR(file_position(a, 1).x - file_position(a, 0).x, 0.010, 1e-6);
  EXPECT_NEAR(file_position(a, 1).y, 5000000.012, 1e-6);
  EXPECT_EQ(a.colors[1], glm::u8vec4(0, 255, 20, 255));
  // Six floats that are not colours are normals.
  const PointSet n = treecut::load_text_cloud_from_memory("0 0 0 0 0 2\n1 0 0 0.5 0 0\n", "n.xyz");
  ASSERT_TRUE(n.has_normals());
  EXPECT_EQ(n.normals[0], glm::vec3(0, 0, 1));
  // PTS: the count line, then x y z intensity r g b.
  std::vector<std::string> warnings;
  const PointSet p =
      treecut::load_text_cloud_from_memory("2\n1 2 3 -100 10 20 30\n4 5 6 -90 40 50 60\n", "p.pts",
                                           [&](const std::string& w) { warnings.push_back(w); });
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p.colors[0], glm::u8vec4(10, 20, 30, 255));
  EXPECT_TRUE(warnings.empty());
  ASSERT_EQ(p.attributes.size(), 1u);
  EXPECT_EQ(p.attributes[0].name, "intensity");
  EXPECT_EQ(p.attributes[0].values, (std::vector<float>{-100.0f, -90.0f}));
  // CSV with a header, columns in any order, unknown ones named.
  warnings.clear();
  const PointSet c = treecut::load_text_cloud_from_memory(
      "\"Classification\",\"Z\",\"X\",\"Y\",\"Red\",\"Green\",\"Blue\"\r\n2,3,1,2,9,8,7\r\n",
      "c.csv", [&](const std::string& w) { warnings.push_back(w); });
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(file_position(c, 0), glm::dvec3(1, 2, 3));
  EXPECT_EQ(c.colors[0], glm::u8vec4(9, 8, 7, 255));
  // A column with one value is kept, once (issue 43, item 1).
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  ASSERT_EQ(c.attributes.size(), 1u);
  EXPECT_TRUE(c.attributes[0].is_constant());
  EXPECT_EQ(c.attributes[0].value(0), 2.0);
  // A header's other columns are attributes, by name and kind.
  const PointSet k = treecut::load_text_cloud_from_memory(
      "x y z intensity class\n0 0 0 10 2\n1 0 0 30 6\n0 1 0 20 2\n", "k.txt");
  ASSERT_EQ(k.attributes.size(), 2u);
  EXPECT_EQ(k.attributes[0].name, "intensity");
  EXPECT_EQ(k.attributes[0].kind, treecut::AttributeKind::measure);
  EXPECT_EQ(k.attributes[1].name, "class");
  EXPECT_EQ(k.attributes[1].kind, treecut::AttributeKind::category);
  EXPECT_EQ(k.attributes[1].values, (std::vector<float>{2, 6, 2}));
}

// `--columns`: a mapping names the columns of a file without a header, or
// instead of its header; `_` skips one.
TEST(TextCloud, AColumnMappingNamesTheColumns) {
  const std::vector<std::string> mapping = {"intensity", "_", "x", "y", "z", "r", "g", "b"};
  const PointSet a = treecut::load_text_cloud_from_memory(
      "7 99 1 2 3 10 20 30\n9 99 4 5 6 40 50 60\n", "a.txt", {}, mapping);
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(file_position(a, 1), glm::dvec3(4, 5, 6));
  EXPECT_EQ(a.colors[1], glm::u8vec4(40, 50, 60, 255));
  ASSERT_EQ(a.attributes.size(), 1u) << "the skipped column is no attribute";
  EXPECT_EQ(a.attributes[0].name, "intensity");
  // A header is replaced by the mapping.
  const PointSet b = treecut::load_text_cloud_from_memory(
      "A,B,C,D\n1,2,3,0.5\n4,5,6,0.7\n", "b.csv", {}, {"x", "y", "z", "reflectance"});
  ASSERT_EQ(b.attributes.size(), 1u);
  EXPECT_EQ(b.attributes[0].name, "reflectance");
  auto error = [](const std::string& text, const std::vector<std::string>& m) {
    try {
      (void)treecut::load_text_cloud_from_memory(text, "m.txt", {}, m);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(loaded)");
  };
  EXPECT_EQ(error("1 2 3 4\n", {"x", "y", "z"}), "m.txt:1: 4 values, where --columns names 3");
  EXPECT_EQ(error("1 2 3\n", {"x", "y", "_"}),
            "m.txt: --columns: the header names no z column (it names x, y, _)");
}

TEST(TextCloud, MalformedLinesAreOneLineNamingTheLine) {
  EXPECT_EQ(text_error_of("1 2 3\n4 5\n"),
            "mem.xyz:2: 2 values, where the first line of points has 3");
  EXPECT_EQ(text_error_of("1 2 3\n4 x 6\n"), "mem.xyz:2: 'x' is not a number");
  EXPECT_EQ(text_error_of("1 2 3\n4 nan-ish 6\n"), "mem.xyz:2: 'nan-ish' is not a number");
  // nan is no value (issue 43, item 17): a point without a position is dropped.
  EXPECT_EQ(text_error_of("1 2 3\n4 nan 6\n"), "(loaded)");
  EXPECT_EQ(text_error_of("nan nan nan\n"),
            "mem.xyz: no points with a finite position (every one is nan)");
  EXPECT_EQ(text_error_of("x y z r g b\n1 2 3 1 2 3\n1 2 3 300 0 0\n"),
            "mem.xyz:3: colour 300 is not a whole number from 0 to 255");
  // Without a header, a 300 on the first lines makes the last three normals.
  EXPECT_EQ(text_error_of("1 2 3 1 2 3\n1 2 3 300 0 0\n"), "(loaded)");
  EXPECT_EQ(text_error_of("3\n1 2 3\n4 5 6\n"),
            "mem.xyz:1: the PTS count line says 3 points, the file has 2");
  EXPECT_EQ(text_error_of("name,other\n1,2\n"),
            "mem.xyz: the header names no x, y, z columns (it names name, other)");
  EXPECT_EQ(text_error_of("# nothing\n"), "mem.xyz: no points (an empty text cloud)");
  EXPECT_EQ(text_error_of("1 2\n"), "mem.xyz: fewer than 3 numbers on a line (x y z)");
  // Every truncation of a small file is loaded or refused with one line.
  const std::string ok = "x,y,z,red,green,blue\n1.5,2,3,1,2,3\n4,5,6.25,4,5,6\n";
  for (std::size_t cut = 0; cut < ok.size(); ++cut) {
    const std::string e = text_error_of(ok.substr(0, cut));
    EXPECT_EQ(e.find('\n'), std::string::npos) << cut;
  }
}

}  // namespace

// ---- PCD ------------------------------------------------------------------

namespace pcd_test {

using treecut::load_pcd_from_memory;

std::string pcd_error_of(const std::string& bytes) {
  try {
    (void)load_pcd_from_memory(bytes, "mem.pcd");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(loaded)";
}

const char* kAsciiPcd =
    "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
    "FIELDS x y z rgb intensity label\nSIZE 4 4 4 4 4 4\nTYPE F F F F F U\nCOUNT 1 1 1 1 1 1\n"
    "WIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n"
    "1 2 3 4.2108e+06 0.5 7\nnan nan nan 0 0 0\n500000.25 2 3 4.2108e+06 1.5 9\n"
    "4 5 6 4.2108e+06 2.5 7\n";

TEST(PcdLoad, AsciiBinaryAndCompressedAgree) {
  using treecut::looks_like_pcd;
  EXPECT_TRUE(looks_like_pcd(kAsciiPcd));
  EXPECT_TRUE(looks_like_pcd("FIELDS x y z\n"));
  EXPECT_FALSE(looks_like_pcd("1 2 3\n"));
  EXPECT_FALSE(looks_like_pcd("ply\n"));
  std::vector<std::string> warnings;
  const PointSet a = load_pcd_from_memory(kAsciiPcd, "a.pcd",
                                          [&](const std::string& w) { warnings.push_back(w); });
  ASSERT_EQ(a.size(), 3u) << "the NaN point (an organized cloud's hole) is dropped";
  EXPECT_NEAR(file_position(a, 1).x, 500000.25, 1e-6) << "positions in double";
  // 4.2108e+06 as a float's bits is 0x4A8080E0: r 0x80, g 0x80, b 0xE0.
  EXPECT_EQ(a.colors[0], glm::u8vec4(0x80, 0x80, 0xE0, 255));
  ASSERT_EQ(a.attributes.size(), 2u);
  EXPECT_EQ(a.attributes[0].name, "intensity");
  EXPECT_EQ(a.attributes[0].values, (std::vector<float>{0.5f, 1.5f, 2.5f}));
  EXPECT_EQ(a.attributes[1].kind, treecut::AttributeKind::category);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], "a.pcd: dropped 1 points without a finite position");

  // The same points written in the three encodings read back alike.
  PointSet p = a;
  p.normals = {{0, 0, 1}, {0, 1, 0}, {1, 0, 0}};
  const auto dir = treecut::test::scratch_dir("pcd");
  for (const treecut::PcdData data :
       {treecut::PcdData::ascii, treecut::PcdData::binary, treecut::PcdData::binary_compressed}) {
    treecut::save_pcd(dir / "p.pcd", p, data);
    const PointSet q = treecut::load_pcd(dir / "p.pcd");
    ASSERT_EQ(q.size(), p.size());
    for (std::size_t i = 0; i < p.size(); ++i) {
      // The file's coordinates, exactly (doubles where there is an origin).
      EXPECT_EQ(exact_position(q, i), exact_position(p, i));
      EXPECT_EQ(q.normals[i], p.normals[i]);
      EXPECT_EQ(q.colors[i], p.colors[i]);
    }
    ASSERT_EQ(q.attributes.size(), 2u);
    EXPECT_EQ(q.attributes[1].values, (std::vector<float>{7, 9, 7}));
  }
}

TEST(PcdLoad, MalformedFilesAreOneLine) {
  const std::string head =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
      "POINTS 2\nDATA ";
  EXPECT_EQ(pcd_error_of(head + "binary\n" + std::string(23, '\0')),
            "mem.pcd: 2 points of 12 bytes declared, the data holds 1");
  EXPECT_EQ(pcd_error_of(head + "ascii\n1 2 3\n"), "mem.pcd: 2 points declared, the file has 1");
  EXPECT_EQ(pcd_error_of(head + "ascii\n1 2 3\n4 5\n"), "mem.pcd: 11: 2 values, the fields have 3");
  EXPECT_EQ(pcd_error_of(head + "zip\n"),
            "mem.pcd: DATA 'zip' (ascii, binary or binary_compressed)");
  EXPECT_EQ(pcd_error_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nDATA ascii\n"),
            "mem.pcd: TYPE 'Q' of field z (I, U or F)");
  EXPECT_EQ(pcd_error_of("FIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n"),
            "mem.pcd: field z: TYPE F of SIZE 3 (I and U: 1, 2, 4, 8; F: 4, 8)");
  EXPECT_EQ(pcd_error_of("FIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nDATA ascii\n1 2\n"),
            "mem.pcd: no x, y and z fields");
  EXPECT_EQ(pcd_error_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nHEIGHT 2\nPOINTS 5\n"
                         "DATA ascii\n"),
            "mem.pcd: WIDTH 3 x HEIGHT 2 is not POINTS 5");
  EXPECT_EQ(pcd_error_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 400000000\nDATA binary\n"),
            "mem.pcd: 400000000 points of 12 bytes declared, the data holds 0");
  EXPECT_EQ(pcd_error_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4000000000\nDATA binary\n"),
            "mem.pcd: more than 2^31 points");
  // Compressed: sizes that cannot be, and damaged LZF.
  std::string sizes;
  put<std::uint32_t>(sizes, 1), put<std::uint32_t>(sizes, 24);
  EXPECT_EQ(pcd_error_of(head + "binary_compressed\n" + sizes + "x"),
            "mem.pcd: the compressed data is damaged (LZF)");
  std::string huge;
  put<std::uint32_t>(huge, 1), put<std::uint32_t>(huge, 24);
  EXPECT_EQ(pcd_error_of(head + "binary_compressed\n" + huge),
            "mem.pcd: the compressed data (1 bytes) runs past the end of the file");
  // Every truncation of a compressed file is refused with one line.
  PointSet p;
  for (int i = 0; i < 50; ++i) p.positions.push_back({float(i), float(i % 7), 0.5f * float(i)});
  const auto dir = treecut::test::scratch_dir("pcd_bad");
  treecut::save_pcd(dir / "c.pcd", p);
  std::ifstream in(dir / "c.pcd", std::ios::binary);
  const std::string full((std::istreambuf_iterator<char>(in)), {});
  ASSERT_EQ(pcd_error_of(full), "(loaded)");
  for (std::size_t cut = 0; cut < full.size(); ++cut) {
    const std::string e = pcd_error_of(full.substr(0, cut));
    EXPECT_EQ(e.rfind("mem.pcd: ", 0), 0u) << cut << ": " << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << cut;
  }
}

}  // namespace pcd_test
