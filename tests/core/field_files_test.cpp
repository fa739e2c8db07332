// Files from the field, round two (issue 43): each case a user ran into,
// as a file made here, read (and written) through the library. The cases
// through the program (exports over a user's file, options, a warm cache's
// notes) are in tests/cli/field_files_gl_test.cpp, the round trips of every
// field in export_round_trip_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/attributes.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/text_cloud.hpp"
#include "treecut/up_axis.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;

const PointAttribute* find(const PointSet& p, const std::string& name) {
  for (const PointAttribute& a : p.attributes) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

// A LAS 1.2 format 1 file of N points on a 1 cm grid: CLASS everywhere,
// point source 7, GPS week times from 245379.3984 s in steps of TIME_STEP.
PointSet survey_tile(std::size_t n, int cls, double time_step) {
  PointSet p;
  PointAttribute c{
      .name = "classification", .kind = AttributeKind::category, .type = ValueType::u8};
  c.values.assign(n, float(cls));
  PointAttribute source{
      .name = "point_source_id", .kind = AttributeKind::category, .type = ValueType::u16};
  source.values.assign(n, 7.0f);
  PointAttribute time{.name = "gps_time", .type = ValueType::f64};
  for (std::size_t i = 0; i < n; ++i) {
    p.positions.push_back({0.01f * float(i % 100), 0.01f * float(i / 100), 0.0f});
    time.wide.push_back(245379.3984 + time_step * double(i));
  }
  p.attributes = {c, source, time};
  return p;
}

// Item 1: an attribute with one value at every point is kept, stored once,
// through the reader, the hierarchy and a LAS written back.
TEST(FieldFiles, AColumnWithOneValueIsKeptOnceAndWrittenBack) {
  const fs::path dir = test::scratch_dir("field_constant");
  save_las(dir / "ground.las", survey_tile(500, 2, 0.001));
  std::vector<std::string> warnings;
  const PointSet p =
      load_las(dir / "ground.las", nullptr, [&](const std::string& w) { warnings.push_back(w); });
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  const PointAttribute* cls = find(p, "classification");
  ASSERT_NE(cls, nullptr) << "an all-ground tile keeps its class";
  EXPECT_TRUE(cls->is_constant());
  EXPECT_EQ(cls->stored(), 0u) << "stored once, not per point";
  EXPECT_EQ(cls->value(123), 2.0);
  EXPECT_EQ(find(p, "point_source_id")->value(0), 7.0);
  save_las(dir / "again.las", p);
  EXPECT_EQ(find(load_las(dir / "again.las"), "classification")->value(499), 2.0);
  const Hierarchy h = build_from_points(p);
  const NodeAttribute* node = h.find_attribute("classification");
  ASSERT_NE(node, nullptr);
  EXPECT_TRUE(node->is_constant());
  EXPECT_EQ(node->offset + double(node->value(h.root())), 2.0);
  EXPECT_EQ(node->min, 2.0);
}

// Item 2: a GPS week time keeps its digits (a float without an offset gave
// 1/64 s), in the points and the hierarchy's range; a double of 1e300 in the
// extra bytes survives a LAS written back; a PCD writes times as doubles.
TEST(FieldFiles, EveryValueKeepsThePrecisionOfItsType) {
  const fs::path dir = test::scratch_dir("field_precision");
  PointSet tile = survey_tile(300, 2, 0.0217);
  PointAttribute big{.name = "big", .type = ValueType::f64};
  for (std::size_t i = 0; i < tile.size(); ++i) big.wide.push_back(i % 2 ? 1e300 : -2.5e-300);
  tile.attributes.push_back(big);
  save_las(dir / "t.las", tile);
  const PointSet p = load_las(dir / "t.las");
  const PointAttribute* time = find(p, "gps_time");
  ASSERT_NE(time, nullptr);
  for (std::size_t i = 0; i < p.size(); ++i) {
    ASSERT_EQ(time->value(i), 245379.3984 + 0.0217 * double(i)) << i;
    ASSERT_EQ(find(p, "big")->value(i), i % 2 ? 1e300 : -2.5e-300) << i;
  }
  const Hierarchy h = build_from_points(p);
  EXPECT_EQ(h.find_attribute("gps_time")->min, 245379.3984);
  EXPECT_EQ(h.find_attribute("gps_time")->max, 245379.3984 + 0.0217 * 299.0);
  save_pcd(dir / "t.pcd", p);
  // The header's FIELDS, SIZE and TYPE lines: gps_time is F 8 (it was F 4).
  const std::string pcd = test::read_all(dir / "t.pcd");
  auto line = [&](const std::string& key) {
    std::vector<std::string> words;
    const std::size_t at = pcd.find("\n" + key + " ") + key.size() + 2;
    std::string rest = pcd.substr(at, pcd.find('\n', at) - at) + " ";
    for (std::size_t b = 0, e; (e = rest.find(' ', b)) != std::string::npos; b = e + 1)
      words.push_back(rest.substr(b, e - b));
    return words;
  };
  const std::vector<std::string> fields = line("FIELDS"), sizes = line("SIZE"),
                                 types = line("TYPE");
  const auto k = static_cast<std::size_t>(std::find(fields.begin(), fields.end(), "gps_time") -
                                          fields.begin());
  ASSERT_LT(k, fields.size());
  EXPECT_EQ(sizes[k], "8");
  EXPECT_EQ(types[k], "F");
  const PointSet q = load_pcd(dir / "t.pcd");
  for (std::size_t i = 0; i < q.size(); ++i)
    ASSERT_EQ(find(q, "gps_time")->value(i), time->value(i)) << i;
}

// Item 2: a PLY of double positions at map coordinates gets an origin (a
// LAS at the same place did; the PLY exported 3 cm off and a file at z =
// 1.2e9 drew nothing), and its doubles are kept for an export.
TEST(FieldFiles, APlyOfDoublesAtMapCoordinatesGetsAnOrigin) {
  std::string body;
  for (int i = 0; i < 50; ++i) {
    const double xyz[3] = {512345.678 + 0.011 * i, 5412345.901 + 0.007 * i, 1.2e9 + 0.013 * i};
    body.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
  }
  const std::string file =
      "ply\nformat binary_little_endian 1.0\nelement vertex 50\nproperty double x\n"
      "property double y\nproperty double z\nend_header\n" +
      body;
  const PointSet p = load_ply_from_memory(file, "far.ply");
  ASSERT_EQ(p.size(), 50u);
  EXPECT_NEAR(p.frame.origin.z, 1.2e9, 1.0);
  ASSERT_EQ(p.exact_positions.size(), 50u);
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(p.exact_positions[static_cast<std::size_t>(i)].x, 512345.678 + 0.011 * i);
    EXPECT_LT(std::fabs(p.positions[static_cast<std::size_t>(i)].z), 1.0f) << "near the origin";
  }
  const fs::path dir = test::scratch_dir("field_ply_doubles");
  save_ply(dir / "again.ply", p);
  const PointSet q = load_ply(dir / "again.ply");
  EXPECT_EQ(q.exact_positions, p.exact_positions) << "written as the doubles they were";
}

// Hostile round: a 64-bit integer past 2^53 (an int64 of 2^62 + 1, a
// uint64 of 2^64 - 1) survives LAS -> LAS and LAS -> PCD -> LAS exactly.
TEST(FieldFiles, SixtyFourBitIntegersPastADoublesRangeAreExact) {
  const fs::path dir = test::scratch_dir("field_int64");
  PointSet p;
  PointAttribute big{.name = "big", .type = ValueType::i64};
  PointAttribute huge{.name = "huge", .type = ValueType::u64};
  // The first integer a double rounds (to 2^53, which passed for exact).
  PointAttribute edge{.name = "edge", .type = ValueType::u64};
  for (int i = 0; i < 10; ++i) {
    p.positions.push_back({float(i), 0.0f, 0.0f});
    big.integers.push_back(i == 1 ? (std::int64_t{1} << 62) + 1 : -i);
    huge.integers.push_back(i == 2 ? -1 : i);  // the bits of 2^64 - 1
    edge.integers.push_back(i == 3 ? (std::int64_t{1} << 53) + 1 : i);
  }
  p.attributes = {big, huge, edge};
  save_las(dir / "a.las", p);
  const PointSet a = load_las(dir / "a.las");
  ASSERT_NE(find(a, "big"), nullptr);
  ASSERT_EQ(find(a, "big")->integers.size(), 10u);
  EXPECT_EQ(find(a, "big")->integers[1], (std::int64_t{1} << 62) + 1);
  EXPECT_EQ(static_cast<std::uint64_t>(find(a, "huge")->integers[2]), ~std::uint64_t{0});
  ASSERT_NE(find(a, "edge"), nullptr);
  ASSERT_EQ(find(a, "edge")->integers.size(), 10u);
  EXPECT_EQ(find(a, "edge")->integers[3], (std::int64_t{1} << 53) + 1);
  save_pcd(dir / "a.pcd", a);
  const PointSet b = load_pcd(dir / "a.pcd");
  save_las(dir / "b.las", b);
  const PointSet c = load_las(dir / "b.las");
  EXPECT_EQ(find(c, "big")->integers, find(a, "big")->integers);
  EXPECT_EQ(find(c, "huge")->integers, find(a, "huge")->integers);
}

// Item 6: a first point at 1e20 is the one dropped and named, not the
// other four (it used to become the origin).
TEST(FieldFiles, AnOutlierIsDroppedAndNamedAndTheRestKept) {
  for (const char* far : {"1e20", "1e30", "1e308"}) {
    std::vector<std::string> warnings;
    const std::string text = std::string(far) + " 0 0\n1 2 3\n4 5 6\n7 8 9\n2 2 2\n";
    const PointSet p = load_text_cloud_from_memory(
        text, "o.xyz", [&](const std::string& w) { warnings.push_back(w); });
    EXPECT_EQ(p.size(), 4u) << far;
    EXPECT_EQ(p.frame.origin, glm::dvec3(0.0)) << far;
    ASSERT_EQ(warnings.size(), 1u) << far;
    EXPECT_EQ(warnings[0].rfind("o.xyz: dropped 1 point beyond the coordinate limit, 1e18 from "
                                "the others or from zero (the first: point 1 at ",
                                0),
              0u)
        << warnings[0];
  }
  const std::string pcd =
      "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 5\nHEIGHT 1\n"
      "POINTS 5\nDATA ascii\n1e20 0 0\n1 2 3\n4 5 6\n7 8 9\n2 2 2\n";
  EXPECT_EQ(load_pcd_from_memory(pcd, "o.pcd").size(), 4u);
  // A cloud wholly past the limit is none: its LAS would be refused by every
  // reader (the hostile round exported one).
  try {
    (void)load_text_cloud_from_memory("0 0 1e19\n1 2 1e19\n", "far.xyz");
    ADD_FAILURE() << "loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no usable points (dropped 2 points beyond the coordinate "
                                         "limit"),
              std::string::npos)
        << e.what();
  }
}

// Item 7: a float cloud near the origin is not "map coordinates" (the
// first point 2.3 1.1 0.4 gave an origin of 2 1 0).
TEST(FieldFiles, OnlyCoordinatesThatNeedAnOriginGetOne) {
  const std::string pcd =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
      "POINTS 3\nDATA ascii\n2.3 1.1 0.4\n5 6 7\n-3 4 1\n";
  const PointSet p = load_pcd_from_memory(pcd, "near.pcd");
  EXPECT_EQ(p.frame.origin, glm::dvec3(0.0));
  EXPECT_EQ(p.positions[0], glm::vec3(2.3f, 1.1f, 0.4f));
  EXPECT_EQ(load_text_cloud_from_memory("2.3 1.1 0.4\n5 6 7\n", "n.xyz").frame.origin,
            glm::dvec3(0.0));
  // Past 32,768 units an origin is taken: the centre of the bounds.
  EXPECT_EQ(load_text_cloud_from_memory("500000 10 0\n500010 20 0\n", "m.xyz").frame.origin,
            glm::dvec3(500005, 15, 0));
}

// Item 9: a regular 20 x 20 terrain grid is z up (its edge columns are
// layers at both ends, not a ground); a depth camera's organized PCD is up
// along the camera's -y, turned by its viewpoint.
TEST(FieldFiles, AGridIsNotOnItsSideAndADepthCameraIsUpright) {
  std::string grid;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      grid += std::to_string(i) + " " + std::to_string(j) + " " +
              std::to_string(0.3 * std::sin(0.4 * i) * std::cos(0.3 * j)) + "\n";
    }
  }
  const Hierarchy terrain = build_from_points(load_text_cloud_from_memory(grid, "g.xyz"));
  EXPECT_EQ(detect_up_axis(terrain).name(), "z") << detect_up_axis(terrain).reason;

  std::string pcd =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 20\nHEIGHT 10\n"
      "VIEWPOINT 1 2 3 1 0 0 0\nPOINTS 200\nDATA ascii\n";
  for (int v = 0; v < 10; ++v) {
    for (int u = 0; u < 20; ++u)
      pcd += std::to_string(0.05 * (u - 10)) + " " + std::to_string(0.05 * (v - 5)) + " 2\n";
  }
  const PointSet camera = load_pcd_from_memory(pcd, "kinect.pcd");
  ASSERT_TRUE(camera.frame.viewpoint);
  EXPECT_EQ(camera.frame.viewpoint->position, glm::dvec3(1, 2, 3));
  const Hierarchy h = build_from_points(camera);
  EXPECT_EQ(detect_up_axis(h).name(), "-y") << detect_up_axis(h).reason;
  // Turned half a turn about z (w = 0, z = 1): up is +y.
  pcd.replace(pcd.find("VIEWPOINT 1 2 3 1 0 0 0"), 23, "VIEWPOINT 0 0 0 0 0 0 1");
  EXPECT_EQ(detect_up_axis(build_from_points(load_pcd_from_memory(pcd, "k.pcd"))).name(), "y");
}

// Item 10: a LAS in EPSG:4326 (longitude, latitude) is drawn in the UTM
// zone of its centre, in metres; --crs names another; a projected file
// stays as it is.
TEST(FieldFiles, GeographicCoordinatesAreReprojectedToMetres) {
  const fs::path dir = test::scratch_dir("field_geographic");
  PointSet seattle;
  seattle.frame.origin = glm::dvec3(-122.33, 47.61, 0.0);
  for (int i = 0; i < 400; ++i) {
    seattle.positions.push_back(
        {1e-4f * float(i % 20), 1e-4f * float(i / 20), 0.5f * float(i % 7)});
  }
  std::string keys;
  for (const std::uint16_t v : {1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326})
    keys.append(reinterpret_cast<const char*>(&v), 2);
  seattle.frame.crs_records.geo_keys = keys;
  save_las(dir / "geo.las", seattle);
  OpenOptions o;
  o.use_cache = false;
  const Hierarchy h = open_model(dir / "geo.las", o).hierarchy;
  EXPECT_EQ(h.frame().crs, "EPSG:32610 (projected), from EPSG:4326 (geographic)");
  // 1.9e-3 degrees of longitude at 47.6 N are about 142 m, of latitude 211 m.
  const glm::vec3 extent = h.bounds_max() - h.bounds_min();
  EXPECT_NEAR(extent.x, 142.0, 3.0);
  EXPECT_NEAR(extent.y, 211.0, 3.0);
  EXPECT_NEAR(extent.z, 3.0, 1e-3) << "heights stay metres";
  EXPECT_NEAR(h.frame().origin.x, 550357.0, 200.0) << "UTM easting of Seattle";
  o.crs = "EPSG:32611";
  EXPECT_EQ(open_model(dir / "geo.las", o).hierarchy.frame().crs,
            "EPSG:32611 (projected), from EPSG:4326 (geographic)");
  o.crs = "EPSG:not-a-code";
  EXPECT_THROW(open_model(dir / "geo.las", o), InputError);
  // Projected input stays.
  for (const std::uint16_t v :
       {std::uint16_t{3072}, std::uint16_t{0}, std::uint16_t{1}, std::uint16_t{32610}})
    keys.append(reinterpret_cast<const char*>(&v), 2);
  keys[6] = 3;  // three keys
  PointSet utm = seattle;
  utm.frame.origin = glm::dvec3(550000.0, 5273000.0, 0.0);
  utm.frame.crs_records.geo_keys = keys;
  save_las(dir / "utm.las", utm);
  o.crs.clear();
  EXPECT_EQ(open_model(dir / "utm.las", o).hierarchy.frame().crs, "EPSG:32610 (projected)");
}

// Item 12: ten collinear points get discs of about their spacing (the
// surface's rule made them four spacings wide), a single point one.
TEST(FieldFiles, RadiiAlongALineComeFromTheSpacingAlongIt) {
  PointSet line;
  for (int i = 0; i < 10; ++i) line.positions.push_back({float(i), 0.0f, 0.0f});
  complete_attributes(line);
  for (const float r : line.radii) {
    EXPECT_GT(r, 0.5f);
    EXPECT_LT(r, 2.0f) << "a spacing of 1";
  }
  // A surface keeps its rule: a 1 cm grid's discs cover it without
  // reaching past a few neighbours.
  PointSet plane;
  for (int i = 0; i < 900; ++i)
    plane.positions.push_back({0.01f * float(i % 30), 0.01f * float(i / 30), 0.0f});
  complete_attributes(plane);
  EXPECT_GT(plane.radii[465], 0.007f);
  EXPECT_LT(plane.radii[465], 0.03f);
}

// Item 15: a PCD that declares 2^31 - 1 points over 60 bytes is refused
// naming the file, before anything is sized from the count.
TEST(FieldFiles, AHugeDeclaredCountIsRefusedBeforeAnythingIsSized) {
  for (const char* data : {"binary", "ascii", "binary_compressed"}) {
    const std::string pcd = std::string(
                                "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                                "COUNT 1 1 1\nWIDTH 2147483647\nHEIGHT 1\nPOINTS "
                                "2147483647\nDATA ") +
                            data + "\n" + std::string(60, '\0');
    try {
      (void)load_pcd_from_memory(pcd, "lie.pcd");
      ADD_FAILURE() << data;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("lie.pcd: ", 0), 0u) << e.what();
    }
  }
  // A line of a million numbers: the warning names the first few, not all.
  std::string wide = "1 2 3";
  for (int i = 0; i < 1000000; ++i) wide += " 7";
  std::vector<std::string> warnings;
  (void)load_text_cloud_from_memory(wide + "\n", "wide.xyz",
                                    [&](const std::string& w) { warnings.push_back(w); });
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_LT(warnings[0].size(), 300u);
  EXPECT_NE(warnings[0].find("and 999928 more"), std::string::npos) << warnings[0];
}

// Item 16: PCD field names are matched without regard to case (PDAL writes
// X Y Z), and separate red, green and blue fields are the colour.
TEST(FieldFiles, PcdFieldNamesIgnoreCaseAndChannelsAreTheColour) {
  const std::string pcd =
      "VERSION 0.7\nFIELDS X Y Z Red Green Blue Intensity\nSIZE 8 8 8 2 2 2 2\n"
      "TYPE F F F U U U U\nCOUNT 1 1 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
      "1 2 3 65535 32768 0 10\n4 5 6 256 512 1024 20\n";
  const PointSet p = load_pcd_from_memory(pcd, "pdal.pcd");
  ASSERT_EQ(p.size(), 2u);
  ASSERT_TRUE(p.has_colors());
  EXPECT_EQ(p.colors[0], glm::u8vec4(255, 128, 0, 255));
  ASSERT_EQ(p.colors16.size(), 2u) << "16 bits kept";
  EXPECT_EQ(p.colors16[1], glm::u16vec3(256, 512, 1024));
  ASSERT_EQ(p.attributes.size(), 1u);
  EXPECT_EQ(p.attributes[0].name, "Intensity");
  EXPECT_EQ(p.attributes[0].type, ValueType::u16);
}

// Hostile round: a PCD that opens with a 70 kB comment, or with WIDTH
// before FIELDS, is a PCD; an ascii PCD is never treecut's own to replace.
TEST(FieldFiles, APcdIsKnownByAnyOfItsHeaderLines) {
  const fs::path dir = test::scratch_dir("field_pcd_header");
  const std::string header =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nHEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3\n4 5 6\n7 8 9\n";
  test::write_text(dir / "comment.pcd", "# " + std::string(70000, 'c') + "\nWIDTH 3\n" + header);
  test::write_text(dir / "width.pcd", "WIDTH 3\n" + header);
  std::string format;
  for (const char* name : {"comment.pcd", "width.pcd"}) {
    EXPECT_EQ(load_point_file(dir / name, {}, &format).size(), 3u) << name;
    EXPECT_EQ(format, "PCD") << name;
  }
  save_pcd(dir / "own.pcd", load_point_file(dir / "width.pcd"), PcdData::ascii);
  EXPECT_FALSE(is_own_pcd(dir / "own.pcd"));
  save_pcd(dir / "own.pcd", load_point_file(dir / "width.pcd"));
  EXPECT_TRUE(is_own_pcd(dir / "own.pcd"));
}

// Item 17: when no other format claims a text, the text reader says what
// is wrong with it (a column named twice, one missing); a first line of
// nan, CR-only line ends and a byte order mark are read.
TEST(FieldFiles, TheTextReaderSaysWhatIsWrongWithAText) {
  const fs::path dir = test::scratch_dir("field_text");
  const auto error = [&](const std::string& name, const std::string& text,
                         const std::vector<std::string>& columns = {}) {
    test::write_text(dir / name, text);
    try {
      (void)load_point_file(dir / name, {}, nullptr, columns);
    } catch (const InputError& e) {
      return std::string(e.what()).substr((dir / name).string().size());
    }
    return std::string("(loaded)");
  };
  EXPECT_EQ(error("dup.csv", "X,Y,X\n1,2,3\n"),
            ": the header names x twice (columns 1 and 3: X, Y, X)");
  EXPECT_EQ(error("dup.csv", "X,Y,X\n1,2,3\n", {"x", "y", "z"}), "(loaded)");
  EXPECT_EQ(error("noz.csv", "x,y\n1,2\n"), ": the header names no z column (it names x, y)");
  EXPECT_EQ(error("nan.xyz", "nan nan nan\n1 2 3\n4 5 6\n"), "(loaded)");
  EXPECT_EQ(error("cr.xyz", "1 2 3\r4 5 6\r7 8 9\r"), "(loaded)");
  EXPECT_EQ(error("bom.xyz",
                  "\xEF\xBB\xBF"
                  "1 2 3\n4 5 6\n"),
            "(loaded)");
  EXPECT_EQ(error("line.xyz", "1 2 3\n4 5 6\n7 eight 9\n"), ":3: 'eight' is not a number");
  EXPECT_EQ(error("nul.xyz", std::string("1 2 3\n4 5\0"
                                         "6\n7 8 9\n",
                                         18))
                .substr(0, 4),
            ":2: ")
      << "a stray byte is named with its line, not as 'not a PLY file'";
  std::string format;
  EXPECT_EQ(load_point_file(dir / "cr.xyz", {}, &format).size(), 3u);
  EXPECT_EQ(format, "text");
}

}  // namespace
}  // namespace treecut
