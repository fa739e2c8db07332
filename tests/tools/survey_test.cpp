// The generated survey (tools/survey.hpp, `treecut gen survey`; issue 44,
// item 4): tiles whose points add up to the asked count, each a pure
// function of the options and its place, distinct positions on a millimetre
// grid (what `gen terrain` lacks at large counts), the fields of a flight,
// ground that continues across tile borders, and the command writing tiles
// that read back with their coordinate system while replacing nothing of the
// user's.
#include "treecut/tools/survey.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "test_support.hpp"
#include "treecut/las.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;
using tools::SurveyOptions;
using tools::SurveyTile;

const PointAttribute& attribute(const PointSet& ps, const std::string& name) {
  for (const PointAttribute& a : ps.attributes) {
    if (a.name == name) return a;
  }
  ADD_FAILURE() << "no attribute " << name;
  static const PointAttribute none;
  return none;
}

// The file's coordinates of point I (what a LAS export writes).
glm::dvec3 file_position(const PointSet& ps, std::size_t i) {
  return ps.frame.origin + glm::dvec3(ps.positions[i]);
}

TEST(SurveyTiles, PointsAddUpAndTheTilesCoverTheArea) {
  SurveyOptions o;
  o.width = 1300, o.height = 700, o.tile = 500, o.density = 3.0;
  const std::vector<SurveyTile> tiles = tools::survey_tiles(o);
  ASSERT_EQ(tiles.size(), 6u);  // 3 columns (500, 500, 300 m) by 2 rows (500, 200 m)
  std::uint64_t total = 0;
  double area = 0;
  std::set<std::string> names;
  for (const SurveyTile& t : tiles) {
    total += t.points;
    area += (t.hi.x - t.lo.x) * (t.hi.y - t.lo.y);
    names.insert(t.file_name);
    // Points by area, to a point.
    EXPECT_NEAR(double(t.points), 3.0 * (t.hi.x - t.lo.x) * (t.hi.y - t.lo.y), 1.0);
  }
  EXPECT_EQ(total, 3u * 1300u * 700u);
  EXPECT_DOUBLE_EQ(area, 1300.0 * 700.0);
  EXPECT_EQ(names.size(), tiles.size());
  EXPECT_EQ(tiles[5].file_name, "tile_501000_5000500.las");
  EXPECT_DOUBLE_EQ(tiles[5].hi.x, 1300.0);
  EXPECT_DOUBLE_EQ(tiles[5].hi.y, 700.0);
  o.density = 0;
  EXPECT_THROW(tools::survey_tiles(o), std::invalid_argument);
}

TEST(Survey, ATileIsAFunctionOfTheOptionsAndItsPlaceAlone) {
  SurveyOptions o;
  o.width = 400, o.height = 200, o.tile = 200, o.density = 2.0;
  const std::vector<SurveyTile> tiles = tools::survey_tiles(o);
  ASSERT_EQ(tiles.size(), 2u);
  const PointSet a = tools::generate_survey_tile(o, tiles[1]);
  tools::generate_survey_tile(o, tiles[0]);  // another tile first changes nothing
  const PointSet b = tools::generate_survey_tile(o, tiles[1]);
  ASSERT_EQ(a.size(), tiles[1].points);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.colors, b.colors);
  ASSERT_EQ(a.attributes.size(), b.attributes.size());
  for (std::size_t k = 0; k < a.attributes.size(); ++k) {
    for (std::size_t i = 0; i < a.size(); i += 97)
      EXPECT_EQ(a.attributes[k].value(i), b.attributes[k].value(i)) << a.attributes[k].name;
  }
  o.seed = 2;
  EXPECT_NE(tools::generate_survey_tile(o, tiles[1]).positions, a.positions);
}

TEST(Survey, PositionsAreDistinctOnTheMillimetreGridAndInTheirTile) {
  SurveyOptions o;
  o.width = 500, o.height = 500, o.tile = 500, o.density = 0.8;  // 200,000 points
  const SurveyTile tile = tools::survey_tiles(o).front();
  const PointSet ps = tools::generate_survey_tile(o, tile);
  ASSERT_EQ(ps.size(), 200000u);
  EXPECT_EQ(ps.frame.crs, "EPSG:32633 (projected)");
  EXPECT_TRUE(ps.frame.z_up);
  std::set<std::tuple<long long, long long, long long>> distinct;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const glm::dvec3 p = file_position(ps, i);
    const glm::dvec3 mm = p * 1000.0;
    // A float of a few hundred metres is within 0.03 mm of its grid value.
    ASSERT_LT(glm::length(mm - glm::round(mm)), 0.05) << i;
    ASSERT_GE(p.x, o.origin.x + tile.lo.x);
    ASSERT_LT(p.x, o.origin.x + tile.hi.x);
    ASSERT_GE(p.y, o.origin.y + tile.lo.y);
    ASSERT_LT(p.y, o.origin.y + tile.hi.y);
    distinct.emplace(std::llround(mm.x), std::llround(mm.y), std::llround(mm.z));
  }
  // `gen terrain` at 60 M points: 18 % distinct. A pulse's later return may
  // repeat its first's x and y, never its height.
  EXPECT_GE(double(distinct.size()), 0.999 * double(ps.size()));
}

TEST(Survey, ReturnsClassesAndTimesAreThoseOfAFlight) {
  SurveyOptions o;
  o.width = 500, o.height = 500, o.tile = 500, o.density = 0.8;
  const PointSet ps = tools::generate_survey_tile(o, tools::survey_tiles(o).front());
  const PointAttribute& number = attribute(ps, "return_number");
  const PointAttribute& of = attribute(ps, "number_of_returns");
  const PointAttribute& cls = attribute(ps, "classification");
  const PointAttribute& time = attribute(ps, "gps_time");
  const PointAttribute& source = attribute(ps, "point_source_id");
  EXPECT_EQ(time.type, ValueType::f64);
  EXPECT_FALSE(time.wide.empty());  // GPS times keep their microseconds
  std::map<int, std::size_t> classes;
  std::map<int, double> height;
  std::size_t multiple = 0;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const int c = int(cls.value(i));
    ++classes[c];
    height[c] += ps.positions[i].z;
    ASSERT_GE(number.value(i), 1.0);
    ASSERT_LE(number.value(i), of.value(i));
    if (of.value(i) > 1) {
      ++multiple;
      // Several returns come through a crown: the last from the ground.
      if (number.value(i) == of.value(i)) {
        EXPECT_TRUE(c == 2 || c == 11) << i;
      } else {
        EXPECT_EQ(c, 5) << i;
      }
    }
    // Flight lines 400 m apart, numbered from 1 in the west.
    EXPECT_EQ(source.value(i), std::floor((file_position(ps, i).x - o.origin.x) / 400.0) + 1.0);
  }
  for (const int c : {2, 5, 6, 11}) EXPECT_GT(classes[c], ps.size() / 50) << "class " << c;
  EXPECT_EQ(classes.size(), 4u);
  EXPECT_GT(multiple, ps.size() / 50);
  // Roofs and crowns stand above the ground, on average by metres.
  EXPECT_GT(height[6] / double(classes[6]), height[2] / double(classes[2]) + 5.0);
  EXPECT_GT(height[5] / double(classes[5]), height[2] / double(classes[2]) + 5.0);
}

TEST(Survey, TheGroundContinuesAcrossTileBorders) {
  SurveyOptions o;
  o.width = 400, o.height = 200, o.tile = 200, o.density = 4.0;
  const std::vector<SurveyTile> tiles = tools::survey_tiles(o);
  // Ground points within 1.5 m of the border x = 200 on either side.
  std::vector<glm::dvec3> west, east;
  for (const SurveyTile& t : tiles) {
    const PointSet ps = tools::generate_survey_tile(o, t);
    const PointAttribute& cls = attribute(ps, "classification");
    for (std::size_t i = 0; i < ps.size(); ++i) {
      const glm::dvec3 p = file_position(ps, i) - o.origin;
      if (cls.value(i) != 2 && cls.value(i) != 11) continue;
      if (std::abs(p.x - 200.0) > 1.5) continue;
      (p.x < 200.0 ? west : east).push_back(p);
    }
  }
  ASSERT_GT(west.size(), 200u);
  ASSERT_GT(east.size(), 200u);
  std::size_t compared = 0;
  for (const glm::dvec3& w : west) {
    double best = 1e9, dz = 0;
    for (const glm::dvec3& e : east) {
      const double d = glm::length(glm::dvec2(w) - glm::dvec2(e));
      if (d < best) best = d, dz = std::abs(w.z - e.z);
    }
    if (best > 1.0) continue;  // no neighbour across: a building's or a crown's shadow
    ++compared;
    // The ground's noise (2 cm) and its slope over a metre, no step.
    EXPECT_LT(dz, 0.25) << "at y " << w.y;
  }
  EXPECT_GT(compared, west.size() / 2);
}

TEST(SurveyCli, WritesTilesThatReadBackAndReplacesNothingOfTheUsers) {
  const fs::path dir = test::scratch_dir("survey_cli");
  const fs::path out = dir / "flight";
  const std::string gen = "gen survey --area 0.2 0.1 --tile 100 -n 40000 -o " + test::quote(out);
  test::CommandResult r = test::run_treecut(gen);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("wrote 2 LAS tiles"), std::string::npos) << r.out;
  std::size_t points = 0;
  for (const char* name : {"tile_500000_5000000.las", "tile_500100_5000000.las"}) {
    LasLoadReport report;
    const PointSet ps = load_las(out / name, &report);
    points += ps.size();
    EXPECT_EQ(report.info.crs, "EPSG:32633 (projected)");
    EXPECT_EQ(report.info.point_format, 3);  // GPS time and RGB
    EXPECT_EQ(report.info.scale[0], 0.001);
  }
  EXPECT_EQ(points, 40000u);
  // Its own tiles it replaces; a user's file of a tile's name it refuses,
  // before writing any tile.
  r = test::run_treecut(gen);
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string first = test::read_all(out / "tile_500000_5000000.las");
  test::write_text(out / "tile_500100_5000000.las", "LASF, a note of mine\n");
  fs::last_write_time(out / "tile_500000_5000000.las", fs::file_time_type{});
  test::expect_failure(test::run_treecut(gen + " --seed 5"), 2, "tile_500100_5000000.las");
  EXPECT_EQ(test::read_all(out / "tile_500100_5000000.las"), "LASF, a note of mine\n");
  EXPECT_EQ(fs::last_write_time(out / "tile_500000_5000000.las"), fs::file_time_type{});
  EXPECT_EQ(test::read_all(out / "tile_500000_5000000.las"), first);
  // A file where the folder would be, and options of other kinds.
  test::write_text(dir / "file", "x");
  test::expect_failure(test::run_treecut("gen survey -n 100 -o " + test::quote(dir / "file")), 2,
                       "is not a folder");
  test::expect_failure(test::run_treecut("gen sphere --tile 50 -o " + test::quote(dir / "s.ply")),
                       2, "--tile is only for survey");
  test::expect_failure(test::run_treecut("gen terrain -n 3000000000"), 2, "at most 2^31");
  test::expect_failure(
      test::run_treecut("gen survey -n 400000000 --tile 5000 -o " + test::quote(dir / "big")), 2,
      "a smaller --tile");
  EXPECT_FALSE(fs::exists(dir / "big"));
}

TEST(SurveyCli, AFolderOfTilesOrSeveralFilesBuildAsOneModel) {
  const fs::path dir = test::scratch_dir("survey_build");
  const fs::path out = dir / "flight";
  ASSERT_EQ(
      test::run_treecut("gen survey --area 0.2 0.1 --tile 100 -n 30000 -o " + test::quote(out))
          .code,
      0);
  const std::string cache = " -o " + test::quote(dir / "flight.tch");
  test::CommandResult r = test::run_treecut("build " + test::quote(out) + cache);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("points      30000\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("; 2 files"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("EPSG:32633 (projected)"), std::string::npos) << r.out;
  r = test::run_treecut("info " + test::quote(dir / "flight.tch"));
  EXPECT_NE(r.out.find("points      30000\n"), std::string::npos) << r.out;
  r = test::run_treecut("build " + test::quote(out / "tile_500000_5000000.las") + " " +
                        test::quote(out / "tile_500100_5000000.las") + " -o " +
                        test::quote(dir / "two.tch"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("points      30000\n"), std::string::npos) << r.out;
  // A compressed tile among them is named, not left out; nothing is written.
  test::write_text(out / "tile_500200_5000000.laz", "LASF and then compressed points");
  const std::string before = test::read_all(dir / "flight.tch");
  test::expect_failure(test::run_treecut("build -f " + test::quote(out) + cache), 2,
                       "tile_500200_5000000.laz");
  EXPECT_EQ(test::read_all(dir / "flight.tch"), before);
  fs::remove(out / "tile_500200_5000000.laz");
  // A tile that ends halfway through its records, among the others (its
  // header read, its points not): named, nothing written.
  const std::string whole = test::read_all(out / "tile_500100_5000000.las");
  test::write_text(out / "tile_500050_5000000.las", whole.substr(0, whole.size() / 2));
  test::expect_failure(test::run_treecut("build -f " + test::quote(out) + cache), 2,
                       "tile_500050_5000000.las");
  EXPECT_EQ(test::read_all(dir / "flight.tch"), before);
  fs::create_directories(dir / "none");
  test::write_text(dir / "none" / "readme.md", "tiles come later\n");
  test::expect_failure(test::run_treecut("build " + test::quote(dir / "none")), 2,
                       "is a directory without point files");
  test::expect_failure(test::run_treecut("build " + test::quote(out / "tile_500000_5000000.las") +
                                         " " + test::quote(dir / "flight.tch")),
                       2, "is a treecut cache already");
}

}  // namespace
}  // namespace treecut
