// `treecut render MODEL.tch --memory SIZE` (issue 45): a cache drawn from
// its pages within the budget, its pages' counters in stats.csv; what does
// not work on a paged model yet refused before any output, in one line.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/model_io.hpp"
#include "treecut/tools/generate.hpp"

namespace fs = std::filesystem;
using treecut::test::quote;
using treecut::test::run_treecut;

namespace {

// A terrain of 100,000 points as a cache (some twenty pages).
fs::path terrain_cache(const fs::path& dir) {
  const fs::path cache = dir / "terrain.tch";
  treecut::save_cache(treecut::build_from_points(treecut::tools::generate_model(
                          treecut::tools::ModelKind::Terrain, 100000, 1)),
                      {1, 2, 3}, cache);
  return cache;
}

// stats.csv as rows of cells, the header first.
std::vector<std::vector<std::string>> read_csv(const fs::path& file) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

const std::string kRun = "--width 160 --height 96 --warmup 3 --sync --no-png ";

}  // namespace

TEST(PagedRender, ACacheWithABudgetIsDrawnFromItsPages) {
  const fs::path dir = treecut::test::scratch_dir("paged_render");
  const fs::path cache = terrain_cache(dir);
  const treecut::test::CommandResult r =
      run_treecut("render " + quote(cache) + " --memory 2M --frames 40 -s recursive " + kRun +
                  "-o " + quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("(paged)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("pages     "), std::string::npos) << r.out;
  const auto rows = read_csv(dir / "out" / "stats.csv");
  ASSERT_GT(rows.size(), 2u);
  const auto& header = rows.front();
  const auto column = [&](const std::string& name) {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    return -1;
  };
  const int resident = column("pages_resident_mib"), loaded = column("pages_loaded");
  ASSERT_GE(resident, 0) << "no pages_resident_mib column";
  ASSERT_GE(loaded, 0) << "no pages_loaded column";
  double most = 0.0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (rows[i].size() <= static_cast<std::size_t>(std::max(resident, loaded))) continue;
    most = std::max(most, std::stod(rows[i][resident]));
  }
  EXPECT_GT(std::stod(rows.back()[loaded]), 0.0) << "no page was read";
  EXPECT_LE(most, 2.0) << "past the budget of 2 MiB";
}

TEST(PagedRender, WhatAPagedModelCannotDoYetIsRefusedInOneLine) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_refusals");
  const fs::path cache = terrain_cache(dir);
  treecut::test::expect_failure(
      run_treecut("render " + quote(cache) + " --memory 2M --frames 2 -s hoq " + kRun + "-o " +
                  quote(dir / "a")),
      2, "GPU queries");
  treecut::test::expect_failure(
      run_treecut("render " + quote(cache) + " --memory 2M --frames 2 --color elevation " + kRun +
                  "-o " + quote(dir / "b")),
      2, "drawn from its pages");
  treecut::test::expect_failure(
      run_treecut("render " + quote(cache) + " --memory 2M --frames 2 --psnr " + kRun + "-o " +
                  quote(dir / "c")),
      2, "full detail");
  EXPECT_FALSE(fs::exists(dir / "a"));
  EXPECT_FALSE(fs::exists(dir / "b"));
}
