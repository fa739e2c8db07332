// The chunked build (issue 44, item 2): a model past its memory budget is
// built in chunks, each with a halo of its neighbours' points, into a
// paged cache; where chunks meet, every point's normal and radius are
// those of a build held whole; attributes, bounds and frame are the
// model's; temporary files go on every exit. Threaded: the chunks' stages
// run on the worker pool (run under TSan in CI).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <map>
#include <regex>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/parallel.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/survey.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;

// A survey of about POINTS in four tiles, into DIR.
void write_survey(const fs::path& dir, double points) {
  tools::SurveyOptions o;
  o.width = o.height = 160.0;
  o.tile = 80.0;
  o.density = points / (o.width * o.height);
  for (const tools::SurveyTile& t : tools::survey_tiles(o))
    save_las(dir / t.file_name, tools::generate_survey_tile(o, t));
}

// What this process holds now: a budget counts it (the build's room is
// what is left).
std::uint64_t resident() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, pages = 0;
  statm >> size >> pages;
  return pages * 4096;
}

Hierarchy load(const fs::path& cache) {
  std::string why;
  std::optional<Hierarchy> h = load_cache(cache, std::nullopt, &why);
  if (!h) throw std::runtime_error(why);
  return std::move(*h);
}

// The files of DIR (what the build left there).
std::vector<std::string> entries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// A point by its position: the survey's are on a millimetre grid, which
// the pages' quantization (well under 0.1 mm here) does not leave.
using Key = std::tuple<long long, long long, long long>;
Key key_of(glm::vec3 p) {
  return {std::llround(p.x * 1000.0), std::llround(p.y * 1000.0), std::llround(p.z * 1000.0)};
}

// MODEL (in DIR) built held whole into DIR/whole.tch and in chunks of a
// 12 MiB room into DIR/chunked.tch; the outline both share checked.
struct TwoBuilds {
  OpenedModel whole, chunked;
  Hierarchy w, c;
};
TwoBuilds build_both_ways(const fs::path& dir, const fs::path& model) {
  TwoBuilds b;
  OpenOptions whole_options;
  whole_options.cache_path = dir / "whole.tch";
  whole_options.memory = std::uint64_t{4} << 30;
  b.whole = open_model(model, whole_options);
  EXPECT_EQ(b.whole.chunked.chunks, 0u);
  OpenOptions chunked_options;
  chunked_options.cache_path = dir / "chunked.tch";
  chunked_options.memory = resident() + (std::uint64_t{12} << 20);
  b.chunked = open_model(model, chunked_options);
  EXPECT_GT(b.chunked.chunked.chunks, 3u) << "the budget cuts the model";
  EXPECT_TRUE(b.chunked.cache_written);
  EXPECT_EQ(b.chunked.input_points, b.whole.input_points);
  b.w = load(dir / "whole.tch");
  b.c = load(dir / "chunked.tch");
  EXPECT_EQ(check_invariants(b.c), "");
  EXPECT_EQ(b.c.leaf_count(), b.w.leaf_count());
  EXPECT_EQ(b.c.bounds_min(), b.w.bounds_min());
  EXPECT_EQ(b.c.bounds_max(), b.w.bounds_max());
  EXPECT_EQ(b.c.frame().origin, b.w.frame().origin);
  return b;
}

TEST(ChunkedBuild, WhereChunksMeetNormalsAndRadiiAreThoseOfABuildHeldWhole) {
  const fs::path dir = test::scratch_dir("chunked_seams");
  fs::create_directories(dir / "tiles");
  write_survey(dir / "tiles", 200000);
  const TwoBuilds both = build_both_ways(dir, dir / "tiles");
  ASSERT_GT(both.chunked.chunked.chunks, 3u) << "the budget cuts the model";
  EXPECT_GT(both.chunked.chunked.halo_points, 0u);
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"chunked.tch", "tiles", "whole.tch"}))
      << "the build's temporary files are gone";

  const Hierarchy& w = both.w;
  const Hierarchy& c = both.c;
  EXPECT_EQ(c.frame().crs, w.frame().crs);
  EXPECT_TRUE(c.frame().normals_estimated);
  EXPECT_EQ(c.notes().format, w.notes().format);
  ASSERT_EQ(c.attributes().size(), w.attributes().size());
  for (std::size_t k = 0; k < w.attributes().size(); ++k) {
    const NodeAttribute &a = c.attributes()[k], &b = w.attributes()[k];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.min, b.min) << a.name;
    EXPECT_EQ(a.max, b.max) << a.name;
    EXPECT_EQ(a.is_constant(), b.is_constant()) << a.name;
  }

  // Every point, matched by its position: the same normal and radius, and
  // (within a node value's float) the same attributes.
  std::map<Key, NodeId> by_position;
  for (NodeId i = 0; i < c.node_count(); ++i)
    if (c.child_count(i) == 0) by_position.emplace(key_of(c.center(i)), i);
  ASSERT_EQ(by_position.size(), c.leaf_count()) << "distinct positions";
  std::size_t matched = 0, same_normal = 0, same_radius = 0;
  for (NodeId i = 0; i < w.node_count(); ++i) {
    if (w.child_count(i) != 0) continue;
    const auto it = by_position.find(key_of(w.center(i)));
    if (it == by_position.end()) continue;
    ++matched;
    const NodeId j = it->second;
    same_normal += c.arrays().normal_cone[j] == w.arrays().normal_cone[i];
    same_radius += c.radius(j) == w.radius(i);
  }
  EXPECT_EQ(matched, w.leaf_count());
  EXPECT_EQ(same_normal, w.leaf_count());
  EXPECT_EQ(same_radius, w.leaf_count());
}

// Text clouds stream too (TextCloudReader): a folder of CSV tiles past the
// budget is built in chunks, batch by batch, into the model one read
// whole gives.
TEST(ChunkedBuild, TextTilesAreReadInBatchesIntoTheModelHeldWhole) {
  const fs::path dir = test::scratch_dir("chunked_text");
  fs::create_directories(dir / "las");
  fs::create_directories(dir / "csv");
  write_survey(dir / "las", 200000);
  for (const auto& e : fs::directory_iterator(dir / "las")) {
    const PointSet ps = load_las(e.path());
    std::string text = "x,y,z,intensity\n";
    char line[128];
    for (std::size_t i = 0; i < ps.size(); ++i) {
      const glm::dvec3 p = ps.frame.origin + glm::dvec3(ps.positions[i]);
      std::snprintf(line, sizeof line, "%.3f,%.3f,%.3f,%g\n", p.x, p.y, p.z,
                    ps.attributes[0].value(i));
      text += line;
    }
    test::write_text(dir / "csv" / e.path().filename().replace_extension(".csv"), text);
  }
  const TwoBuilds b = build_both_ways(dir, dir / "csv");
  ASSERT_GT(b.chunked.chunked.chunks, 3u) << "the budget cuts the model";
  EXPECT_EQ(b.chunked.format, "text");
}

// So do binary PLY and PCD clouds (PlyReader, PcdReader): tiles saved in
// either (map coordinates in doubles, an intensity) build in batches into
// the model held whole.
TEST(ChunkedBuild, PlyAndPcdTilesAreReadInBatchesIntoTheModelHeldWhole) {
  tools::SurveyOptions o;
  o.width = o.height = 160.0;
  o.tile = 80.0;
  o.density = 200000 / (o.width * o.height);
  for (const std::string format : {"PLY", "PCD"}) {
    SCOPED_TRACE(format);
    const fs::path dir = test::scratch_dir("chunked_" + format);
    fs::create_directories(dir / "tiles");
    for (const tools::SurveyTile& t : tools::survey_tiles(o)) {
      const PointSet tile = tools::generate_survey_tile(o, t);
      const fs::path name = dir / "tiles" / t.file_name;
      if (format == "PLY") save_ply(fs::path(name).replace_extension(".ply"), tile);
      if (format == "PCD")
        save_pcd(fs::path(name).replace_extension(".pcd"), tile, PcdData::binary);
    }
    const fs::path first = fs::directory_iterator(dir / "tiles")->path();
    EXPECT_TRUE(format == "PLY" ? PlyReader(first).streams() : PcdReader(first).streams());
    const TwoBuilds b = build_both_ways(dir, dir / "tiles");
    EXPECT_EQ(b.chunked.format, format);
    EXPECT_EQ(b.c.attributes().size(), b.w.attributes().size());
  }
}

// Two chunks in flight (each lane on a chunk of its own, sharing the
// scratch files; what TSan checks) write the cache that one at a time
// writes, byte for byte: each chunk's result is its own whatever the
// schedule, and the file is written in the plan's order.
TEST(ChunkedBuild, TwoChunksAtOnceWriteTheCacheThatOneAtATimeWrites) {
  if (worker_count() < 2) GTEST_SKIP() << "one hardware thread";
  const fs::path dir = test::scratch_dir("chunked_lanes");
  fs::create_directories(dir / "tiles");
  write_survey(dir / "tiles", 300000);
  std::string caches[2];
  for (const unsigned threads : {1u, 2u}) {
    OpenOptions o;
    o.cache_path = dir / ("m" + std::to_string(threads) + ".tch");
    o.build.threads = threads;
    // Room for chunks of about 150 k points: two lanes of 75 k.
    o.memory = resident() + (std::uint64_t{48} << 20);
    const OpenedModel m = open_model(dir / "tiles", o);
    ASSERT_GT(m.chunked.chunks, 2u) << "the budget cuts the model";
    EXPECT_EQ(m.chunked.lanes, threads);
    caches[threads - 1] = test::cache_but_identity_time(test::read_all(*o.cache_path));
  }
  EXPECT_FALSE(caches[0].empty());
  EXPECT_TRUE(caches[0] == caches[1]) << "the same bytes";
}

// Under a sanitizer (GCC says so with a macro, Clang with __has_feature).
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
constexpr bool kSanitized = __has_feature(address_sanitizer) || __has_feature(thread_sanitizer);
#else
constexpr bool kSanitized = false;
#endif

// A budget that leaves ROOM MiB beside what the program holds (16-17 MiB;
// several times that under the sanitizers), as the program says it when a
// budget leaves too little.
std::string budget_beside_program(double room) {
  const fs::path dir = test::scratch_dir("chunked_program");
  write_survey(dir, 20000);
  const test::CommandResult r = test::run_treecut("build " + test::quote(dir) + " --memory 1K -o " +
                                                  test::quote(dir / "m.tch"));
  std::smatch m;
  if (!std::regex_search(r.out, m, std::regex("of which the program holds ([0-9.]+) MiB"))) {
    ADD_FAILURE() << r.out;
    return "32M";
  }
  return std::to_string(static_cast<int>(std::stod(m[1]) + room + 1.0)) + "M";
}

// The command: a survey past its budget builds in chunks within it (2 M
// points under 32 MiB; a smaller one under the sanitizers, whose shadow
// memory the budget's program share holds), prints how, and leaves only
// its cache.
TEST(ChunkedBuildCli, ASurveyPastItsBudgetBuildsInChunksWithinIt) {
  const char* points = kSanitized ? "300000" : "2000000";
  const std::string budget = kSanitized ? budget_beside_program(15) : "32M";
  const fs::path dir = test::scratch_dir("chunked_cli");
  const test::CommandResult gen = test::run_treecut("gen survey -n " + std::string(points) +
                                                    " --tile 250 -o " + test::quote(dir / "tiles"));
  ASSERT_EQ(gen.code, 0) << gen.out;
  const test::CommandResult r =
      test::run_treecut("build " + test::quote(dir / "tiles") + " --memory " + budget + " -o " +
                        test::quote(dir / "m.tch"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      r.out, m, std::regex("chunks +([0-9]+), [0-9]+ at a time, the largest ([0-9]+)")))
      << r.out;
  EXPECT_GT(std::stoul(m[1]), 1u);
  ASSERT_TRUE(std::regex_search(
      r.out, m, std::regex("memory +peak ([0-9.]+) MiB of a budget of ([0-9.]+) MiB; temporary")))
      << r.out;
  // The sanitizers' shadow memory and quarantine are not the build's.
  if (!kSanitized) {
    EXPECT_LE(std::stod(m[1]), std::stod(m[2])) << r.out;
  }
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"m.tch", "tiles"}));
  const test::CommandResult info = test::run_treecut("info " + test::quote(dir / "m.tch"));
  ASSERT_EQ(info.code, 0) << info.out;
  EXPECT_NE(info.out.find("points      " + std::string(points) + "\n"), std::string::npos)
      << info.out;
}

// A disk that fills during a chunked build: one line naming where and why,
// exit 1, and nothing left on the disk.
TEST(ChunkedBuildCli, AFullDiskEndsTheBuildWithOneLineAndLeavesNothing) {
  auto disk = test::SmallDisk::mount("chunked_full", 2u << 20);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here (needs root)";
  const fs::path dir = test::scratch_dir("chunked_full_tiles");
  write_survey(dir, 200000);
  const test::CommandResult r =
      test::run_treecut("build " + test::quote(dir) + " --memory " + budget_beside_program(15) +
                        " -o " + test::quote(disk->path() / "m.tch"));
  test::expect_failure(r, 1, "No space left on device");
  EXPECT_NE(r.out.find("m.tch"), std::string::npos) << r.out;
  EXPECT_TRUE(entries(disk->path()).empty()) << "temporary files left";
}

// The build killed (SIGKILL: no chance to clean up) leaves its temporary
// files; the next build of the same cache removes them. SIGTERM removes
// them itself.
TEST(ChunkedBuildCli, TemporaryFilesGoOnSignalsAndAfterAKill) {
  const fs::path dir = test::scratch_dir("chunked_kill");
  fs::create_directories(dir / "tiles");
  write_survey(dir / "tiles", 300000);
  const fs::path bin = fs::path(TREECUT_BINARY_DIR) / "demo" / "treecut";
  const std::string budget = budget_beside_program(15);
  const auto start = [&] {
    const pid_t pid = ::fork();
    if (pid == 0) {
      const std::string tiles = (dir / "tiles").string(), out = (dir / "m.tch").string();
      ::freopen("/dev/null", "w", stdout);
      ::freopen("/dev/null", "w", stderr);
      ::execl(bin.c_str(), bin.c_str(), "build", tiles.c_str(), "--memory", budget.c_str(), "-o",
              out.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    return pid;
  };
  // Until the build has temporary files (its scratch beside the cache).
  const auto scratch_appears = [&] {
    for (int i = 0; i < 6000; ++i) {
      for (const std::string& name : entries(dir))
        if (name.find(".tmp-") != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  };
  for (const int sig : {SIGKILL, SIGTERM}) {
    const pid_t pid = start();
    ASSERT_GT(pid, 0);
    ASSERT_TRUE(scratch_appears()) << "no temporary file within a minute";
    ::kill(pid, sig);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the build ended before the signal";
    const std::vector<std::string> left = entries(dir);
    if (sig == SIGTERM) {
      EXPECT_EQ(left, (std::vector<std::string>{"tiles"})) << "SIGTERM removes them";
      continue;
    }
    EXPECT_GT(left.size(), 1u) << "a kill -9 leaves them";
    const test::CommandResult again =
        test::run_treecut("build " + test::quote(dir / "tiles") + " --memory " + budget + " -o " +
                          test::quote(dir / "m.tch"));
    ASSERT_EQ(again.code, 0) << again.out;
    EXPECT_EQ(entries(dir), (std::vector<std::string>{"m.tch", "tiles"}))
        << "the next build removed what the killed one left";
    fs::remove(dir / "m.tch");
  }
}

// A tile that cannot be read halfway through a folder: named, exit 2, no
// cache and no temporary file.
TEST(ChunkedBuildCli, ATileCutShortIsNamedAndNothingIsWritten) {
  const fs::path dir = test::scratch_dir("chunked_cut");
  fs::create_directories(dir / "tiles");
  write_survey(dir / "tiles", 200000);
  std::vector<fs::path> tiles;
  for (const auto& e : fs::directory_iterator(dir / "tiles")) tiles.push_back(e.path());
  std::sort(tiles.begin(), tiles.end());
  ASSERT_EQ(tiles.size(), 4u);
  fs::resize_file(tiles[2], fs::file_size(tiles[2]) / 2);
  const test::CommandResult r =
      test::run_treecut("build " + test::quote(dir / "tiles") + " --memory " +
                        budget_beside_program(15) + " -o " + test::quote(dir / "m.tch"));
  test::expect_failure(r, 2, tiles[2].filename().string());
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"tiles"}));
}

}  // namespace
}  // namespace treecut
