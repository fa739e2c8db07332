// Replays the inputs the fuzz targets once failed on (tests/fuzz/regressions/,
// listed with the outcome each fix established in MANIFEST.tsv) through the
// checks of the fuzz targets themselves (tests/fuzz/fuzz_checks.hpp), in every
// build configuration: one test per file, named after it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "../fuzz/fuzz_checks.hpp"
#include "hierarchy/cache_checksum.hpp"
#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/ply.hpp"
#include "treecut/text_cloud.hpp"

namespace {

namespace fs = std::filesystem;
using treecut::test::read_all;

const fs::path kRegressions = fs::path(TREECUT_SOURCE_DIR) / "tests" / "fuzz" / "regressions";

struct Regression {
  std::string file;    // under regressions/: ply/NAME, points/NAME or cache/NAME
  std::string expect;  // ply, points: ok | error; cache: rejected | ok (once resealed)
  std::string detail;  // a warning (ply ok), the message (error), the reason (rejected), or -
  std::string what;
};

std::vector<Regression> read_manifest() {
  std::vector<Regression> rows;
  std::ifstream in(kRegressions / "MANIFEST.tsv");
  std::string line;
  std::getline(in, line);  // column names
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::istringstream fields(line);
    Regression r;
    std::getline(fields, r.file, '\t');
    std::getline(fields, r.expect, '\t');
    std::getline(fields, r.detail, '\t');
    std::getline(fields, r.what);
    rows.push_back(r);
  }
  return rows;
}

std::string test_name(const testing::TestParamInfo<Regression>& info) {
  std::string name;
  for (char c : info.param.file) name += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return name;
}

// As the fuzz targets: a PLY's or PCD's batches (3 rows each) give what
// the whole read gives.
template <class Reader, class Load>
void replay_batches(const std::string& bytes, Load&& load) {
  long long whole = -1;
  bool far = false;
  const treecut::WarningSink note = [&](const std::string& w) {
    far = far || treecut::fuzz::about_far_points(w);
  };
  try {
    whole = static_cast<long long>(load(note).size());
  } catch (const treecut::InputError& e) {
    note(e.what());
  }
  EXPECT_EQ(treecut::fuzz::check_batches<Reader>(bytes, whole, far, 3), "");
}

void replay_ply(const Regression& r, const std::string& bytes) {
  replay_batches<treecut::PlyReader>(bytes, [&](const treecut::WarningSink& note) {
    return treecut::load_ply_from_memory(bytes, "regression.ply", nullptr, note);
  });
  std::vector<std::string> warnings;
  treecut::PlyLoadReport report;
  treecut::PointSet points;
  try {
    points = treecut::load_ply_from_memory(bytes, "regression.ply", &report,
                                           [&](const std::string& w) { warnings.push_back(w); });
  } catch (const treecut::InputError& e) {
    ASSERT_EQ(r.expect, "error") << "rejected: " << e.what();
    EXPECT_NE(std::string(e.what()).find(r.detail), std::string::npos) << e.what();
    return;
  }
  ASSERT_EQ(r.expect, "ok") << "loaded " << points.size() << " points";
  if (r.detail != "-") {
    EXPECT_TRUE(
        std::any_of(warnings.begin(), warnings.end(),
                    [&](const std::string& w) { return w.find(r.detail) != std::string::npos; }))
        << "no warning mentions '" << r.detail << "'";
  }
  EXPECT_EQ(treecut::fuzz::check_point_set(points), "");
  EXPECT_EQ(points.size() + report.dropped_nonfinite, report.vertices_in_file);
  EXPECT_EQ(treecut::fuzz::check_builds(std::move(points)), "");
}

// As points_fuzz: the reader open_model would choose.
void replay_points(const Regression& r, const std::string& bytes) {
  if (!treecut::looks_like_las(bytes) && treecut::looks_like_pcd(bytes)) {
    replay_batches<treecut::PcdReader>(bytes, [&](const treecut::WarningSink& note) {
      return treecut::load_pcd_from_memory(bytes, "regression.pcd", note);
    });
  }
  treecut::LasLoadReport report;
  treecut::PointSet points;
  bool las = false;
  try {
    points = treecut::fuzz::load_point_bytes(bytes, report, las);
  } catch (const treecut::InputError& e) {
    ASSERT_EQ(r.expect, "error") << "rejected: " << e.what();
    EXPECT_NE(std::string(e.what()).find(r.detail), std::string::npos) << e.what();
    return;
  }
  ASSERT_EQ(r.expect, "ok") << "loaded " << points.size() << " points";
  EXPECT_EQ(treecut::fuzz::check_point_set(points), "");
  if (las) {
    EXPECT_EQ(points.size(), report.info.point_count);
  }
  EXPECT_EQ(treecut::fuzz::check_builds(std::move(points)), "");
}

// As cache_fuzz does: the bytes as they are, then resealed with a valid
// checksum. The expectation is about the resealed file, which reaches the
// structural checks.
void replay_cache(const Regression& r, std::string bytes) {
  ASSERT_GT(bytes.size(), 8u);
  // A directory per input: CTest runs the inputs in parallel processes.
  const fs::path file =
      treecut::test::scratch_dir("fuzz_regression_" + fs::path(r.file).stem().string()) /
      "input.tch";
  for (bool sealed : {false, true}) {
    SCOPED_TRACE(sealed ? "resealed" : "as found");
    if (sealed)
      treecut::detail::reseal_cache(reinterpret_cast<unsigned char*>(bytes.data()), bytes.size());
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
    std::string why;
    const auto h = treecut::load_cache(file, std::nullopt, &why);
    if (h) {
      EXPECT_EQ(treecut::fuzz::check_loaded_hierarchy(*h), "");
    } else {
      EXPECT_FALSE(why.empty());
    }
    if (!sealed) continue;
    if (r.expect == "ok") {
      EXPECT_TRUE(h) << why;
    } else {
      ASSERT_EQ(r.expect, "rejected");
      EXPECT_FALSE(h) << "loaded";
      EXPECT_NE(why.find(r.detail), std::string::npos) << why;
    }
  }
}

class FuzzRegression : public testing::TestWithParam<Regression> {};

TEST_P(FuzzRegression, BehavesAsItsFixEstablished) {
  const Regression& r = GetParam();
  SCOPED_TRACE(r.file + ": " + r.what);
  const fs::path path = kRegressions / r.file;
  ASSERT_TRUE(fs::is_regular_file(path)) << path;
  if (r.file.rfind("ply/", 0) == 0) {
    replay_ply(r, read_all(path));
  } else if (r.file.rfind("points/", 0) == 0) {
    replay_points(r, read_all(path));
  } else {
    ASSERT_EQ(r.file.rfind("cache/", 0), 0u) << "neither ply/, points/ nor cache/";
    replay_cache(r, read_all(path));
  }
}

INSTANTIATE_TEST_SUITE_P(Manifest, FuzzRegression, testing::ValuesIn(read_manifest()), test_name);

TEST(FuzzRegressions, EveryFileIsInTheManifest) {
  const auto rows = read_manifest();
  ASSERT_FALSE(rows.empty());
  for (const char* target : {"ply", "points", "cache"}) {
    for (const auto& e : fs::directory_iterator(kRegressions / target)) {
      const std::string file = std::string(target) + "/" + e.path().filename().string();
      EXPECT_TRUE(std::any_of(rows.begin(), rows.end(),
                              [&](const Regression& r) { return r.file == file; }))
          << file << " is not in MANIFEST.tsv";
    }
  }
}

}  // namespace
