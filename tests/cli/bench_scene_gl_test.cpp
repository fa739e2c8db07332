// `treecut bench scene` (demo/bench_scene.cpp) on a tiny generated city
// block (50 buildings): the tables print, the culling accuracy against the
// renderer's exact ObjectId reference is a number in [0, 1] with no object
// wrongly culled (an object with a pixel of its id is never culled), the
// per-frame CSV has a row per frame, and bad input (a missing scene, a bad
// camera path, a model that is not a scene) is one line naming the file with
// exit code 2. GL: the command draws through OSMesa; tests/CMakeLists.txt
// labels a test gl when its source names a splat GL header or runs "render "
// or "view " (the line above is what gives this one its label).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;

struct Tiny {
  fs::path dir, scene, walk;
};

const Tiny& tiny() {
  static const Tiny t = [] {
    Tiny x;
    // One folder per test: ctest runs this file's tests as parallel
    // processes, and scratch_dir empties the folder it returns.
    x.dir = test::scratch_dir(std::string("bench_scene/") +
                              ::testing::UnitTest::GetInstance()->current_test_info()->name());
    x.scene = x.dir / "tiny.scene";
    x.walk = x.dir / "tiny.campath";
    const test::CommandResult r =
        test::run_treecut("gen city-block --objects 50 -n 3000 -o " + test::quote(x.scene) +
                          " --walk " + test::quote(x.walk));
    EXPECT_EQ(r.code, 0) << r.out;
    return x;
  }();
  return t;
}

// The table row that starts with `prefix` (a markdown row), split into cells.
std::vector<std::string> row_of(const std::string& out, const std::string& prefix) {
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(prefix, 0) != 0) continue;
    std::vector<std::string> cells;
    std::istringstream l(line);
    for (std::string c; std::getline(l, c, '|');) {
      const auto b = c.find_first_not_of(' '), e = c.find_last_not_of(' ');
      if (b != std::string::npos) cells.push_back(c.substr(b, e - b + 1));
    }
    return cells;
  }
  return {};
}

std::size_t lines_of(const std::string& text) {
  std::size_t n = 0;
  for (const char c : text) n += c == '\n' ? 1 : 0;
  if (!text.empty() && text.back() != '\n') ++n;
  return n;
}

TEST(BenchScene, PrintsTheTablesWithAnAccuracyInUnitRangeAndNoneWronglyCulled) {
  const Tiny& t = tiny();
  const fs::path csv = t.dir / "csv";
  const test::CommandResult r = test::run_treecut(
      "bench scene " + test::quote(t.scene) + " --path " + test::quote(t.walk) +
      " --frames 6 --from 15 --to 50 --width 320 --height 240 -p points=20000 --csv " +
      test::quote(csv));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("| frames | in frustum | seen (reference) | truly hidden | HZM culled | "
                       "wrongly culled |"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("| | culling on | culling off | on / off |"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("| culler | accuracy | culled | wrongly | rescued |"), std::string::npos)
      << r.out;

  // The accuracy row: frames, in frustum, seen, hidden, culled, wrongly, in
  // the AOS, "accuracy (culled / hidden)", min / max.
  const std::vector<std::string> acc = row_of(r.out, "| 6 |");
  ASSERT_EQ(acc.size(), 9u) << r.out;
  EXPECT_EQ(acc[5], "0") << "an object the reference sees was culled\n" << r.out;
  // "A (C / H)", read with sscanf: <regex> under ASan's -O1 trips GCC 12's
  // false -Wmaybe-uninitialized inside libstdc++.
  double accuracy = -1.0;
  unsigned long culled = 0, hidden = 0;
  char close = 0;
  ASSERT_EQ(std::sscanf(acc[7].c_str(), "%lf (%lu / %lu%c", &accuracy, &culled, &hidden, &close), 4)
      << acc[7];
  EXPECT_EQ(close, ')') << acc[7];
  EXPECT_GE(accuracy, 0.0);
  EXPECT_LE(accuracy, 1.0);
  EXPECT_LE(culled, hidden);
  EXPECT_GT(std::stod(acc[1]), 0.0) << "the walk sees objects in the frustum";
  EXPECT_GT(std::stod(acc[2]), 0.0) << "the reference sees objects";

  // Culling on never gives the seen objects fewer splats in all than off, at
  // the same N, and never selects more than N.
  const std::vector<std::string> sel = row_of(r.out, "| splats selected |");
  ASSERT_EQ(sel.size(), 4u) << r.out;
  EXPECT_LE(std::stod(sel[1]), 20000.0);
  EXPECT_LE(std::stod(sel[2]), 20000.0);
  const std::vector<std::string> psnr = row_of(r.out, "| luma PSNR against full detail, dB |");
  ASSERT_GE(psnr.size(), 3u) << r.out;
  EXPECT_GT(std::stod(psnr[1]), 0.0);
  EXPECT_GT(std::stod(psnr[2]), 0.0);

  // The diagnosis' first row is the strategy's own settings rerun: it culls
  // exactly what the strategy culled.
  const std::vector<std::string> own = row_of(r.out, "| AOS 32, CT 0.55, finer 2, 320 cells (the");
  ASSERT_EQ(own.size(), 5u) << r.out;
  EXPECT_EQ(std::stoul(own[2]), culled) << r.out;
  EXPECT_EQ(own[3], "0") << r.out;

  std::ifstream in(csv / "scene_tiny.csv");
  ASSERT_TRUE(in) << r.out;
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(lines_of(text.str()), 7u) << text.str();  // header + 6 frames
  EXPECT_EQ(text.str().rfind("frame,in_frustum,seen,hidden,culled,wrongly,accuracy,", 0), 0u);
}

TEST(BenchScene, BadInputIsOneLineNamingTheFileAndExitCode2) {
  const Tiny& t = tiny();
  const auto expect_one_line = [](const test::CommandResult& r, const std::string& name) {
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(lines_of(r.out), 1u) << r.out;
    EXPECT_NE(r.out.find(name), std::string::npos) << r.out;
  };
  const fs::path missing = t.dir / "none.scene";
  expect_one_line(test::run_treecut("bench scene " + test::quote(missing) + " --path " +
                                    test::quote(t.walk) + " --frames 1"),
                  missing.string());

  const fs::path bad_path = t.dir / "bad.campath";
  {
    std::ofstream o(bad_path);
    o << "treecut-camera-path 1\n0 1 2 3\n";
  }
  expect_one_line(test::run_treecut("bench scene " + test::quote(t.scene) + " --path " +
                                    test::quote(bad_path) + " --frames 1"),
                  bad_path.string());
  const fs::path no_path = t.dir / "none.campath";
  expect_one_line(test::run_treecut("bench scene " + test::quote(t.scene) + " --path " +
                                    test::quote(no_path) + " --frames 1"),
                  no_path.string());

  // A model file is not a scene.
  const fs::path ply = t.dir / "sphere.ply";
  ASSERT_EQ(test::run_treecut("gen sphere -n 2000 -o " + test::quote(ply)).code, 0);
  expect_one_line(test::run_treecut("bench scene " + test::quote(ply) + " --path " +
                                    test::quote(t.walk) + " --frames 1"),
                  ply.string());
  // A CSV target that is not an earlier run's is the user's: refused.
  const fs::path csv = t.dir / "user";
  fs::create_directories(csv);
  {
    std::ofstream o(csv / "scene_tiny.csv");
    o << "my data\n";
  }
  expect_one_line(test::run_treecut("bench scene " + test::quote(t.scene) + " --path " +
                                    test::quote(t.walk) + " --frames 1 --csv " + test::quote(csv)),
                  (csv / "scene_tiny.csv").string());
  std::ifstream kept(csv / "scene_tiny.csv");
  std::string first;
  std::getline(kept, first);
  EXPECT_EQ(first, "my data");
}

}  // namespace
}  // namespace treecut
