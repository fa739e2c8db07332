// The chunked build (issue 44, item 2): a model past its memory budget is
// built in chunks, each with a halo of its neighbours' points, into a
// paged cache; where chunks meet, every point's normal and radius are
// those of a build held whole; attributes, bounds and frame are the
// model's; temporary files go on every exit. Threaded: the chunks' stages
// run on the worker pool (run under TSan in CI).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
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

TEST(ChunkedBuild, WhereChunksMeetNormalsAndRadiiAreThoseOfABuildHeldWhole) {
  const fs::path dir = test::scratch_dir("chunked_seams");
  fs::create_directories(dir / "tiles");
  write_survey(dir / "tiles", 200000);
  OpenOptions whole_options;
  whole_options.cache_path = dir / "whole.tch";
  whole_options.memory = std::uint64_t{4} << 30;
  const OpenedModel whole = open_model(dir / "tiles", whole_options);
  EXPECT_EQ(whole.chunked.chunks, 0u);

  OpenOptions chunked_options;
  chunked_options.cache_path = dir / "chunked.tch";
  chunked_options.memory = resident() + (std::uint64_t{12} << 20);
  const OpenedModel chunked = open_model(dir / "tiles", chunked_options);
  ASSERT_GT(chunked.chunked.chunks, 3u) << "the budget cuts the model";
  EXPECT_GT(chunked.chunked.halo_points, 0u);
  EXPECT_TRUE(chunked.cache_written);
  EXPECT_EQ(chunked.input_points, whole.input_points);
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"chunked.tch", "tiles", "whole.tch"}))
      << "the build's temporary files are gone";

  const Hierarchy w = load(dir / "whole.tch");
  const Hierarchy c = load(dir / "chunked.tch");
  EXPECT_EQ(check_invariants(c), "");
  EXPECT_EQ(c.leaf_count(), w.leaf_count());
  EXPECT_EQ(c.bounds_min(), w.bounds_min());
  EXPECT_EQ(c.bounds_max(), w.bounds_max());
  EXPECT_EQ(c.frame().origin, w.frame().origin);
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

}  // namespace
}  // namespace treecut
