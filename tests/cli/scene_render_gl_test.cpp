// `treecut render SCENE.scene` as a user runs it (issue 13): a scene goes
// through the Feedback Stage (a strategy instance per object), the frame
// layer (SceneCutBuffer + Renderer::draw_scene) and the CLI's reports.
//  - one object with the identity transform renders exactly as its model
//    (same strategy, path and mode: the PNGs are byte for byte the same);
//  - a few objects of two models: every stats.csv row has the splats of the
//    union cut and the points of every object, summary.json counts the
//    objects and one draw call per pass, however many objects;
//  - a generated city block along its walk renders;
//  - a malformed scene is exit code 2 and one line naming FILE:LINE, and so
//    is a per-object strategy past its limit (before any output).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace fs = std::filesystem;
using treecut::test::quote;
using treecut::test::run_treecut;

namespace {

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << p;
}

// The rows of stats.csv as maps from column name to text.
std::vector<std::vector<std::pair<std::string, std::string>>> read_csv(const fs::path& p) {
  std::istringstream in(read_text(p));
  std::string line;
  std::vector<std::string> header;
  std::vector<std::vector<std::pair<std::string, std::string>>> rows;
  auto split = [](const std::string& l) {
    std::vector<std::string> f;
    std::string x;
    std::istringstream s(l);
    while (std::getline(s, x, ',')) f.push_back(x);
    return f;
  };
  if (std::getline(in, line)) header = split(line);
  while (std::getline(in, line)) {
    const std::vector<std::string> f = split(line);
    std::vector<std::pair<std::string, std::string>> row;
    for (std::size_t i = 0; i < header.size() && i < f.size(); ++i)
      row.emplace_back(header[i], f[i]);
    rows.push_back(row);
  }
  return rows;
}

std::string column(const std::vector<std::pair<std::string, std::string>>& row,
                   const std::string& name) {
  for (const auto& [k, v] : row) {
    if (k == name) return v;
  }
  return {};
}

// A camera path that frames the unit sphere, from afar to close.
void write_sphere_path(const fs::path& p) {
  write_text(p,
             "treecut-camera-path 1\n"
             "0 0 0.5 3.5  0 0 0  0 1 0 45\n"
             "1 2.0 0.5 2.0  0 0 0  0 1 0 45\n"
             "2 1.2 0.2 0.9  0 0 0  0 1 0 45\n");
}

std::size_t count_lines(const std::string& s) {
  std::size_t n = 0;
  std::istringstream in(s);
  std::string line;
  while (std::getline(in, line)) n += !line.empty();
  return n;
}

TEST(SceneRender, OneObjectWithTheIdentityRendersAsItsModel) {
  const fs::path dir = treecut::test::scratch_dir("scene_render_identity");
  const fs::path model = dir / "sphere.ply";
  ASSERT_EQ(run_treecut("gen sphere -n 20000 -o " + quote(model)).code, 0);
  write_text(dir / "one.scene", "treecut-scene 1\nmodel s sphere.ply\nobject s\n");
  write_sphere_path(dir / "near.campath");
  for (const std::string mode : {"fast", "hq"}) {
    for (const std::string strategy : {"optimization", "recursive"}) {
      const std::string common = " --sync --frames 4 --warmup 2 --width 160 --height 120 --mode " +
                                 mode + " -s " + strategy + " --path " +
                                 quote(dir / "near.campath") + " -o ";
      const fs::path a = dir / ("model_" + mode + "_" + strategy);
      const fs::path b = dir / ("scene_" + mode + "_" + strategy);
      const auto ra = run_treecut("render " + quote(model) + common + quote(a));
      ASSERT_EQ(ra.code, 0) << ra.out;
      const auto rb = run_treecut("render " + quote(dir / "one.scene") + common + quote(b));
      ASSERT_EQ(rb.code, 0) << rb.out;
      // fast: one splat pass, hq: two (visibility, blend), each one draw call.
      const std::string calls = mode == "fast" ? "1.0" : "2.0";
      EXPECT_NE(rb.out.find("1 objects, " + calls + " draw calls per frame"), std::string::npos)
          << rb.out;
      const auto rows_a = read_csv(a / "stats.csv"), rows_b = read_csv(b / "stats.csv");
      ASSERT_EQ(rows_a.size(), 4u);
      ASSERT_EQ(rows_b.size(), 4u);
      for (int f = 0; f < 4; ++f) {
        EXPECT_EQ(column(rows_a[f], "splats_drawn"), column(rows_b[f], "splats_drawn"));
        char name[32];
        std::snprintf(name, sizeof name, "frame_%05d.png", f);
        const std::string pa = read_text(a / name), pb = read_text(b / name);
        ASSERT_FALSE(pa.empty()) << (a / name);
        // The same encoder on the same pixels: the same bytes.
        EXPECT_TRUE(pa == pb) << mode << " " << strategy << " frame " << f << " differs";
      }
    }
  }
}

TEST(SceneRender, ObjectsOfTwoModelsDrawTheirUnionCutInOneCallPerPass) {
  const fs::path dir = treecut::test::scratch_dir("scene_render_union");
  ASSERT_EQ(run_treecut("gen sphere -n 6000 -o " + quote(dir / "ball.ply")).code, 0);
  write_text(dir / "five.scene",
             "treecut-scene 1\n"
             "model ball ball.ply\n"
             "generate house building 7 5000\n"
             "object ball translate -3 0 0\n"
             "object ball scale 0.5 translate 0 0 1\n"
             "object house scale 2 2 3 translate 3 0 -1\n"
             "object house scale 1 1 2 turn 90 translate 0 4 -1\n"
             "object ball scale 1 2 1 translate 0 -4 0\n");
  write_text(dir / "one.scene", "treecut-scene 1\ngenerate house building 7 5000\nobject house\n");
  for (const std::string mode : {"fast", "hq"}) {
    const fs::path out = dir / ("five_" + mode);
    const auto r = run_treecut("render " + quote(dir / "five.scene") +
                               " --sync --frames 6 --warmup 0 --no-png --width 200 --height 150 "
                               "--mode " +
                               mode + " -o " + quote(out));
    ASSERT_EQ(r.code, 0) << r.out;
    // "scene     five.scene: 5 objects of 2 models, N points at full detail"
    const auto at = r.out.find("5 objects of 2 models, ");
    ASSERT_NE(at, std::string::npos) << r.out;
    const std::string points = r.out.substr(at + 23, r.out.find(' ', at + 23) - (at + 23));
    const auto rows = read_csv(out / "stats.csv");
    ASSERT_EQ(rows.size(), 6u);
    std::size_t largest = 0;
    for (const auto& row : rows) {
      // Every object's cut covers its model: the points of all of them.
      EXPECT_EQ(column(row, "points_represented"), points);
      const std::size_t splats = std::stoul(column(row, "splats_drawn"));
      EXPECT_GE(splats, 5u);  // at least a node per object
      largest = std::max(largest, splats);
    }
    EXPECT_GT(largest, 5u);  // the strategy refined the roots
    const nlohmann::json j = nlohmann::json::parse(read_text(out / "summary.json"));
    ASSERT_TRUE(j.contains("scene")) << j.dump();
    EXPECT_EQ(j["scene"]["objects"], 5);
    EXPECT_EQ(j["scene"]["models"], 2);
    // One draw call per pass, whatever the number of objects: the same as a
    // scene of one object in the same mode (fast has one pass).
    const fs::path one = dir / ("one_" + mode);
    const auto r1 = run_treecut("render " + quote(dir / "one.scene") +
                                " --sync --frames 2 --warmup 0 --no-png --width 200 --height 150 "
                                "--mode " +
                                mode + " -o " + quote(one));
    ASSERT_EQ(r1.code, 0) << r1.out;
    const nlohmann::json j1 = nlohmann::json::parse(read_text(one / "summary.json"));
    EXPECT_EQ(j["scene"]["max_draw_calls"], j1["scene"]["max_draw_calls"]);
    EXPECT_EQ(j["scene"]["mean_draw_calls"], j["scene"]["max_draw_calls"]);
    if (mode == "fast") {
      EXPECT_EQ(j["scene"]["max_draw_calls"], 1);
    }
  }
}

TEST(SceneRender, AGeneratedCityBlockRendersAlongItsWalk) {
  const fs::path dir = treecut::test::scratch_dir("scene_render_city");
  const fs::path scene = dir / "city.scene";
  ASSERT_EQ(run_treecut("gen city-block --objects 60 -n 1500 -o " + quote(scene)).code, 0);
  const fs::path walk =
      fs::path(TREECUT_SOURCE_DIR) / "assets" / "paths" / "city_block_walk.campath";
  const auto r = run_treecut("render " + quote(scene) + " --path " + quote(walk) +
                             " --sync --frames 3 --warmup 1 --width 160 --height 120 -o " +
                             quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::is_regular_file(dir / "out" / "frame_00002.png"));
  const nlohmann::json j = nlohmann::json::parse(read_text(dir / "out" / "summary.json"));
  EXPECT_GT(j["scene"]["objects"].get<int>(), 60);  // the buildings and their ground tiles
}

TEST(SceneRender, AMalformedSceneIsExitTwoAndOneLineNamingFileAndLine) {
  const fs::path dir = treecut::test::scratch_dir("scene_render_bad");
  write_text(dir / "bad.scene",
             "treecut-scene 1\n"
             "generate house building 1 100\n"
             "object house sclae 2\n");
  const fs::path out = dir / "out";
  const auto r = run_treecut("render " + quote(dir / "bad.scene") + " --frames 2 -o " + quote(out));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(count_lines(r.out), 1u) << r.out;
  EXPECT_NE(r.out.find("bad.scene:3: "), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
  // An object of a model the file never declared: the same.
  write_text(dir / "bad2.scene", "treecut-scene 1\nobject ghost\n");
  const auto r2 = run_treecut("render " + quote(dir / "bad2.scene") + " -o " + quote(out));
  EXPECT_EQ(r2.code, 2) << r2.out;
  EXPECT_EQ(count_lines(r2.out), 1u) << r2.out;
  EXPECT_NE(r2.out.find("bad2.scene:2: "), std::string::npos) << r2.out;
}

TEST(SceneRender, PerObjectStrategiesPastTheLimitAreRefusedBeforeAnyOutput) {
  // 1,900 instances of a model of 100,000 points: more than 2^28 nodes of
  // per-object state in all (kMaxPerObjectNodes).
  const fs::path dir = treecut::test::scratch_dir("scene_render_limit");
  std::string text = "treecut-scene 1\ngenerate big building 3 100000\n";
  for (int i = 0; i < 1900; ++i) text += "object big translate " + std::to_string(i) + " 0 0\n";
  write_text(dir / "big.scene", text);
  const fs::path out = dir / "out";
  const auto r = run_treecut("render " + quote(dir / "big.scene") + " --frames 2 -o " + quote(out));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(count_lines(r.out), 1u) << r.out;
  EXPECT_NE(r.out.find("big.scene: a scene of 1900 objects"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("use a scene-level strategy"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
