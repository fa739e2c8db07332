// Many files are one model (issue 44, item 1): a LAS file read in batches
// gives what one read gives; PointSet::append joins the
// points of the files of one cloud, every attribute at the precision both
// files allow; a model of several files is keyed on all of them, opened
// through one cache, and refuses files of another coordinate system; a
// build past the memory is refused with its figures before it reads. The
// command-line cases (a folder of survey tiles) are in
// tests/tools/survey_test.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/survey.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;

const PointAttribute* find(const PointSet& ps, const std::string& name) {
  for (const PointAttribute& a : ps.attributes) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

// A tile of N points on a line from START along x, at map coordinates.
PointSet tile(std::size_t n, glm::dvec3 origin, float start) {
  PointSet p;
  p.frame.origin = origin;
  p.frame.crs = "EPSG:32633 (projected)";
  p.frame.crs_records.geo_keys = tools::geotiff_keys_for_epsg(32633);
  for (std::size_t i = 0; i < n; ++i) p.positions.emplace_back(start + float(i), 0.5f, 1.0f);
  return p;
}

TEST(PointSetAppend, PositionsMoveToTheFirstOriginAndArraysStayInStep) {
  PointSet a = tile(3, {500000, 5000000, 100}, 0.0f);
  a.colors.assign(3, glm::u8vec4(10, 20, 30, 255));
  a.normals.assign(3, glm::vec3(0, 0, 1));
  a.triangles.emplace_back(0, 1, 2);
  PointSet b = tile(2, {500100, 5000000, 90}, 0.0f);
  b.triangles.emplace_back(0, 1, 1);
  a.append(std::move(b));
  ASSERT_EQ(a.size(), 5u);
  EXPECT_EQ(a.frame.origin, glm::dvec3(500000, 5000000, 100));
  // B's first point: 500100 + 0 in file coordinates, 100 from A's origin.
  EXPECT_EQ(a.positions[3], glm::vec3(100.0f, 0.5f, -9.0f));
  // Only A had normals: estimated for all, as for a file without them.
  EXPECT_FALSE(a.has_normals());
  // B had no colours: the grey of an uncoloured file.
  ASSERT_EQ(a.colors.size(), 5u);
  EXPECT_EQ(a.colors[4], glm::u8vec4(200, 200, 200, 255));
  ASSERT_EQ(a.triangles.size(), 2u);
  EXPECT_EQ(a.triangles[1], glm::uvec3(3, 4, 4));
}

TEST(PointSetAppend, AttributesJoinByNameAtThePrecisionOfBoth) {
  PointSet a = tile(3, {0, 0, 0}, 0.0f);
  a.attributes.push_back({.name = "classification",
                          .kind = AttributeKind::category,
                          .type = ValueType::u8,
                          .constant = 2.0});
  a.attributes.push_back({.name = "gps_time",
                          .type = ValueType::f64,
                          .wide = {245379.3984375001, 245380.5, 245381.25}});
  a.attributes.push_back(
      {.name = "id", .type = ValueType::u64, .integers = {std::int64_t(9007199254740993), 1, 2}});
  PointSet b = tile(2, {0, 0, 0}, 10.0f);
  b.attributes.push_back({.name = "classification",
                          .kind = AttributeKind::category,
                          .type = ValueType::u8,
                          .constant = 6.0});
  b.attributes.push_back({.name = "id", .type = ValueType::u64, .values = {7.0f, 8.0f}});
  b.attributes.push_back({.name = "height", .type = ValueType::f32, .values = {1.5f, 2.5f}});
  a.append(std::move(b));
  ASSERT_EQ(a.attributes.size(), 4u);
  const PointAttribute* cls = find(a, "classification");
  ASSERT_NE(cls, nullptr);
  EXPECT_EQ(cls->kind, AttributeKind::category);
  EXPECT_EQ(cls->type, ValueType::u8);
  EXPECT_EQ(cls->value(2), 2.0);
  EXPECT_EQ(cls->value(3), 6.0);
  const PointAttribute* time = find(a, "gps_time");
  ASSERT_NE(time, nullptr);
  EXPECT_EQ(time->value(0), 245379.3984375001);  // a double stays a double
  EXPECT_TRUE(std::isnan(time->value(3)));       // B has none
  const PointAttribute* id = find(a, "id");
  ASSERT_NE(id, nullptr);
  ASSERT_EQ(id->integers.size(), 5u);  // past 2^53: every value as its integer
  EXPECT_EQ(id->integers[0], std::int64_t(9007199254740993));
  EXPECT_EQ(id->integers[4], 8);
  const PointAttribute* height = find(a, "height");
  ASSERT_NE(height, nullptr);
  EXPECT_TRUE(std::isnan(height->value(0)));  // A has none
  EXPECT_EQ(height->value(4), 2.5);
}

TEST(PointSetAppend, FieldsOfOtherTypesOrScalesBecomeDoubles) {
  PointSet a = tile(2, {0, 0, 0}, 0.0f);
  a.attributes.push_back({.name = "intensity", .type = ValueType::u8, .values = {1, 2}});
  a.attributes.push_back(
      {.name = "angle", .type = ValueType::i16, .scale = 0.006, .values = {0.006f, 0.012f}});
  PointSet b = tile(2, {0, 0, 0}, 5.0f);
  b.attributes.push_back({.name = "intensity", .type = ValueType::u16, .values = {300, 60000}});
  b.attributes.push_back({.name = "angle", .type = ValueType::i8, .values = {3, -4}});
  a.append(std::move(b));
  EXPECT_EQ(find(a, "intensity")->type, ValueType::u16);  // the wider integer
  EXPECT_EQ(find(a, "intensity")->value(3), 60000.0);
  EXPECT_EQ(find(a, "angle")->type, ValueType::f64);  // scales differ: the values themselves
  EXPECT_EQ(find(a, "angle")->scale, 1.0);
  EXPECT_EQ(find(a, "angle")->value(3), -4.0);
  EXPECT_FLOAT_EQ(float(find(a, "angle")->value(1)), 0.012f);
}

TEST(PointSetAppend, FloatsFromAnotherOffsetStayFloatsOrBecomeDoubles) {
  PointSet a = tile(2, {0, 0, 0}, 0.0f);
  a.attributes.push_back(
      {.name = "t", .type = ValueType::f64, .offset = 1e6, .values = {0.5f, 1.5f}});
  PointSet b = tile(2, {0, 0, 0}, 5.0f);
  b.attributes.push_back({.name = "t", .type = ValueType::f64, .values = {3.0f, 4.0f}});
  a.append(std::move(b));
  const PointAttribute* t = find(a, "t");
  ASSERT_EQ(t->values.size(), 4u);  // 3 - 1e6 is a float: still floats from 1e6
  EXPECT_EQ(t->value(0), 1000000.5);
  EXPECT_EQ(t->value(2), 3.0);
  PointSet c = tile(2, {0, 0, 0}, 9.0f);
  c.attributes.push_back({.name = "t", .type = ValueType::f64, .wide = {0.1, 7.25}});
  a.append(std::move(c));
  t = find(a, "t");
  EXPECT_TRUE(t->values.empty());  // 0.1 - 1e6 is no float: doubles for all
  ASSERT_EQ(t->wide.size(), 6u);
  EXPECT_EQ(t->value(1), 1000001.5);
  EXPECT_EQ(t->value(4), 0.1);
  EXPECT_EQ(t->value(5), 7.25);
}

TEST(LasReader, BatchesJoinedAreTheWholeFile) {
  const fs::path dir = test::scratch_dir("las_batches");
  tools::SurveyOptions survey;
  survey.width = survey.height = survey.tile = 40.0;
  survey.density = 5.0;  // 8,000 points of a flight: classes, returns, GPS times, colours
  PointSet made = tools::generate_survey_tile(survey, tools::survey_tiles(survey).front());
  // A 16-bit colour channel past 255 only after the first batch.
  made.colors16.assign(made.size(), glm::u16vec3(100, 120, 140));
  made.colors16.back() = glm::u16vec3(40000, 120, 140);
  save_las(dir / "t.las", made);
  const PointSet whole = load_las(dir / "t.las");
  LasReader reader(dir / "t.las");
  EXPECT_EQ(reader.remaining(), made.size());
  PointSet joined;
  std::size_t batches = 0;
  for (PointSet batch = reader.next(777); batch.size() != 0; batch = reader.next(777)) {
    EXPECT_LE(batch.size(), 777u);
    EXPECT_EQ(batch.frame.origin, whole.frame.origin);  // fixed when the file opened
    joined.append(std::move(batch));
    ++batches;
  }
  EXPECT_EQ(batches, 11u);
  EXPECT_EQ(reader.remaining(), 0u);
  ASSERT_EQ(joined.size(), whole.size());
  EXPECT_EQ(joined.positions, whole.positions);
  EXPECT_EQ(joined.frame.crs, whole.frame.crs);
  EXPECT_EQ(joined.frame.resolution, whole.frame.resolution);
  EXPECT_EQ(joined.colors16, whole.colors16);
  // The last record's bright channel, sampled by the first batch, makes
  // the first batches' colours 16-bit too.
  EXPECT_EQ(joined.colors, whole.colors);
  ASSERT_EQ(joined.attributes.size(), whole.attributes.size());
  for (std::size_t k = 0; k < whole.attributes.size(); ++k) {
    const PointAttribute& a = joined.attributes[k];
    const PointAttribute& b = whole.attributes[k];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.type, b.type) << a.name;
    for (std::size_t i = 0; i < whole.size(); ++i) ASSERT_EQ(a.value(i), b.value(i)) << a.name << i;
  }
  // Positions alone (the chunked build's counting pass): the same floats
  // in the same frame, and nothing else.
  LasReader positions(dir / "t.las");
  const PointSet p = positions.next(5000, true);
  ASSERT_EQ(p.size(), 5000u);
  EXPECT_EQ(p.frame.origin, whole.frame.origin);
  EXPECT_EQ(p.frame.crs, whole.frame.crs);
  EXPECT_TRUE(std::equal(p.positions.begin(), p.positions.end(), whole.positions.begin()));
  EXPECT_TRUE(p.attributes.empty());
  EXPECT_FALSE(p.has_colors());
  EXPECT_TRUE(p.exact_positions.empty());
  EXPECT_EQ(positions.next(made.size(), true).size(), made.size() - 5000);
}

TEST(ManyFiles, AModelOfSeveralFilesIsKeyedOnAllOfThemInOrder) {
  const fs::path dir = test::scratch_dir("many_files_key");
  save_las(dir / "a.las", tile(50, {500000, 5000000, 0}, 0.0f));
  save_las(dir / "b.las", tile(60, {500100, 5000000, 0}, 0.0f));
  const std::vector<fs::path> ab{dir / "a.las", dir / "b.las"}, ba{dir / "b.las", dir / "a.las"};
  const CacheKey k_ab = cache_key_for(ab, 7), k_ba = cache_key_for(ba, 7);
  EXPECT_EQ(k_ab.source_size, fs::file_size(ab[0]) + fs::file_size(ab[1]));
  EXPECT_NE(k_ab.content_hash, k_ba.content_hash);
  EXPECT_FALSE(cache_key_matches(k_ab, k_ba));
  EXPECT_NE(k_ab.content_hash, cache_key_for(ab[0], 7).content_hash);
  // One file's key is its own (the caches of single files stay valid).
  EXPECT_EQ(cache_key_for(std::vector<fs::path>{ab[0]}, 7).content_hash,
            cache_key_for(ab[0], 7).content_hash);
  // The same bytes under the same names elsewhere: the same content.
  fs::create_directories(dir / "copy");
  fs::copy_file(ab[0], dir / "copy" / "a.las");
  fs::copy_file(ab[1], dir / "copy" / "b.las");
  const CacheKey copied =
      cache_key_for(std::vector<fs::path>{dir / "copy" / "a.las", dir / "copy" / "b.las"}, 7);
  EXPECT_TRUE(cache_key_matches(k_ab, copied));
  EXPECT_FALSE(cache_identity_serves(k_ab, copied));  // other inodes: hashed, not trusted
  // An edited tile is another model.
  save_las(dir / "copy" / "b.las", tile(61, {500100, 5000000, 0}, 0.0f));
  EXPECT_FALSE(cache_key_matches(
      k_ab,
      cache_key_for(std::vector<fs::path>{dir / "copy" / "a.las", dir / "copy" / "b.las"}, 7)));
}

TEST(ManyFiles, AFolderOpensAsOneModelThroughOneCache) {
  const fs::path dir = test::scratch_dir("many_files_open");
  fs::create_directories(dir / "tiles");
  save_las(dir / "tiles" / "a.las", tile(300, {500000, 5000000, 0}, 0.0f));
  save_las(dir / "tiles" / "b.LAS", tile(200, {500400, 5000000, 0}, 0.0f));
  test::write_text(dir / "tiles" / "notes.md", "not a point file\n");
  ASSERT_EQ(point_files_in(dir / "tiles").size(), 2u);
  OpenOptions o;
  o.cache_path = dir / "tiles.tch";
  const OpenedModel built = open_model(dir / "tiles", o);
  EXPECT_FALSE(built.from_cache);
  EXPECT_EQ(built.files, 2u);
  EXPECT_EQ(built.input_points, 500u);
  EXPECT_EQ(built.hierarchy.leaf_count(), 500u);
  EXPECT_NE(built.hierarchy.notes().format.find("2 files"), std::string::npos);
  // The second tile's points lie 400 m east of the first's.
  EXPECT_NEAR(built.hierarchy.bounds_max().x - built.hierarchy.bounds_min().x, 599.0, 1e-3);
  const OpenedModel again = open_model(dir / "tiles", o);
  EXPECT_TRUE(again.from_cache);
  // A tile more: another model, rebuilt.
  save_las(dir / "tiles" / "c.las", tile(10, {500800, 5000000, 0}, 0.0f));
  const OpenedModel more = open_model(dir / "tiles", o);
  EXPECT_FALSE(more.from_cache);
  EXPECT_EQ(more.input_points, 510u);
  // A file of another coordinate system is named with the first.
  PointSet other = tile(10, {500800, 5000000, 0}, 0.0f);
  other.frame.crs = "EPSG:32632 (projected)";
  other.frame.crs_records.geo_keys = tools::geotiff_keys_for_epsg(32632);
  save_las(dir / "tiles" / "d.las", other);
  try {
    open_model(dir / "tiles", o);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("d.las"), std::string::npos) << what;
    EXPECT_NE(what.find("a.las"), std::string::npos) << what;
  }
  fs::create_directories(dir / "empty");
  EXPECT_THROW(open_model(dir / "empty", o), InputError);
}

TEST(BuildMemory, TheHeadersSayHowManyPointsABuildHolds) {
  const fs::path dir = test::scratch_dir("build_memory");
  const PointSet p = tile(1000, {500000, 5000000, 0}, 0.0f);
  save_las(dir / "a.las", p);
  save_ply(dir / "a.ply", p);
  save_pcd(dir / "a.pcd", p);
  std::string text;
  for (int i = 0; i < 1000; ++i) text += std::to_string(i) + ".125 2.5 -3.75\n";
  test::write_text(dir / "a.xyz", text);
  test::write_text(dir / "bad.ply", "ply\nformat nonsense\n");
  const auto points = [](const fs::path& f) {
    return build_memory_estimate(std::span(&f, 1)).points;
  };
  EXPECT_EQ(points(dir / "a.las"), 1000u);
  EXPECT_EQ(points(dir / "a.ply"), 1000u);
  EXPECT_EQ(points(dir / "a.pcd"), 1000u);
  EXPECT_NEAR(double(points(dir / "a.xyz")), 1000.0, 50.0);  // by its lines' length
  EXPECT_EQ(points(dir / "bad.ply"), 0u);                    // the reader says what is wrong
  const std::vector<fs::path> all{dir / "a.las", dir / "a.ply"};
  const BuildMemory two = build_memory_estimate(all);
  EXPECT_EQ(two.points, 2000u);
  EXPECT_EQ(two.bytes, 1000u * kLasBuildBytesPerPoint + 1000u * kBuildBytesPerPoint);

  EXPECT_EQ(build_memory_problem("m", two, two.bytes, true), "");
  EXPECT_EQ(build_memory_problem("m", two, 0, false), "");  // unknown: no limit
  const std::string over = build_memory_problem("m", two, two.bytes - 1, false);
  EXPECT_EQ(over.rfind("m: 2000 points need about ", 0), 0u) << over;
  EXPECT_NE(over.find("--memory SIZE"), std::string::npos) << over;
  const std::string huge = build_memory_problem(
      "m", {kMaxBuildPoints + 1, (kMaxBuildPoints + 1) * kBuildBytesPerPoint}, 0, false);
  EXPECT_NE(huge.find("one hierarchy holds at most 2000000000"), std::string::npos) << huge;
  EXPECT_GT(available_memory(), 0u);
}

// Past its budget a build goes in chunks (chunked_build_threaded_test.cpp);
// below the least a chunked build needs, or with no cache to build into,
// it is refused with its figures before it reads.
TEST(BuildMemory, ABuildPastItsBudgetThatCannotGoInChunksIsRefusedBeforeItReads) {
  const fs::path dir = test::scratch_dir("build_memory_refused");
  save_las(dir / "a.las", tile(1000, {500000, 5000000, 0}, 0.0f));
  OpenOptions o;
  o.cache_path = dir / "a.tch";
  o.memory = 1000 * kLasBuildBytesPerPoint - 1;
  const auto refusal = [&] {
    try {
      open_model(dir / "a.las", o);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("not refused");
  };
  EXPECT_NE(refusal().find(" MiB, of which the program holds "), std::string::npos) << refusal();
  EXPECT_NE(refusal().find("a build in chunks needs 8 MiB beside it"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "a.tch"));
  o.use_cache = false;  // nothing to build into
  EXPECT_NE(refusal().find("a.las: 1000 points need about"), std::string::npos) << refusal();
  o.use_cache = true;
  o.memory = 1000 * kLasBuildBytesPerPoint + (std::uint64_t{64} << 20);  // and the program
  EXPECT_EQ(open_model(dir / "a.las", o).input_points, 1000u);
  // From its cache, nothing is built: no budget applies.
  o.memory = 1;
  EXPECT_TRUE(open_model(dir / "a.las", o).from_cache);
  const test::CommandResult r = test::run_treecut(
      "build --memory 64K " + test::quote(dir / "a.las") + " -f -o " + test::quote(dir / "b.tch"));
  test::expect_failure(r, 1, "--memory allows 0.1 MiB, of which the program holds");
  EXPECT_FALSE(fs::exists(dir / "b.tch"));
}

}  // namespace
}  // namespace treecut
