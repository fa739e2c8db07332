// `treecut render MODEL.tch --memory SIZE` (issue 45): a cache drawn from
// its pages within the budget, its pages' counters in stats.csv; what does
// not work on a paged model yet refused before any output, in one line.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "image_compare.hpp"
#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/model_io.hpp"
#include "treecut/tools/generate.hpp"

namespace fs = std::filesystem;
using treecut::test::quote;
using treecut::test::run_treecut;

namespace {

// A terrain of POINTS points as a cache (100,000: some twenty pages).
fs::path terrain_cache(const fs::path& dir, std::size_t points = 100000) {
  const fs::path cache = dir / "terrain.tch";
  treecut::save_cache(treecut::build_from_points(treecut::tools::generate_model(
                          treecut::tools::ModelKind::Terrain, points, 1)),
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

// Column NAME of stats.csv's rows (the header first), as numbers.
std::vector<double> column(const std::vector<std::vector<std::string>>& rows,
                           const std::string& name) {
  std::vector<double> values;
  if (rows.empty()) return values;
  const auto at = std::find(rows.front().begin(), rows.front().end(), name);
  if (at == rows.front().end()) return values;
  const auto i = static_cast<std::size_t>(at - rows.front().begin());
  for (std::size_t r = 1; r < rows.size(); ++r)
    if (i < rows[r].size() && !rows[r][i].empty()) values.push_back(std::stod(rows[r][i]));
  return values;
}

// `treecut render CACHE OPTIONS -s recursive`, headless, into DIR/out.
treecut::test::CommandResult render_paged(const fs::path& dir, const fs::path& cache,
                                          const std::string& options,
                                          const std::string& strategy = "recursive") {
  return run_treecut("render " + quote(cache) + " " + options + " -s " + strategy + " " + kRun +
                     "-o " + quote(dir / "out"));
}

// `treecut render MODEL OPTIONS` standing still (40 frames of warm-up with
// --sync, then 4) into OUT: its last frame and its output.
std::pair<treecut::splat::Image, std::string> settled_frame(const fs::path& model,
                                                            const std::string& options,
                                                            const fs::path& out) {
  const treecut::test::CommandResult r =
      run_treecut("render " + quote(model) + " " + options +
                  " --frames 4 --warmup 40 --sync --width 160 --height 96 -o " + quote(out));
  EXPECT_EQ(r.code, 0) << r.out;
  return {treecut::test::load_png(out / "frame_00003.png"), r.out};
}

}  // namespace

TEST(PagedRender, ACacheWithABudgetIsDrawnFromItsPages) {
  const fs::path dir = treecut::test::scratch_dir("paged_render");
  const fs::path cache = terrain_cache(dir);
  const treecut::test::CommandResult r = render_paged(dir, cache, "--memory 2M --frames 40");
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

// hoq on a paged model: its queries are answered (each carries its sphere)
// and its blocks ask for pages, within the budget.
TEST(PagedRender, HoqDrawsAPagedModelAskingItsQueries) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_hoq");
  const fs::path cache = terrain_cache(dir);
  const treecut::test::CommandResult r = render_paged(dir, cache, "--memory 2M --frames 40", "hoq");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = read_csv(dir / "out" / "stats.csv");
  const std::vector<double> answered = column(rows, "queries_answered"),
                            loaded = column(rows, "pages_loaded"),
                            ram = column(rows, "pages_resident_mib");
  ASSERT_EQ(answered.size(), 40u) << r.out;
  ASSERT_EQ(loaded.size(), 40u) << r.out;
  EXPECT_GT(std::accumulate(answered.begin(), answered.end(), 0.0), 0.0) << "no query answered";
  EXPECT_GT(loaded.back(), 0.0) << "no page was read";
  EXPECT_LE(*std::max_element(ram.begin(), ram.end()), 2.0) << "past the budget of 2 MiB";
}

TEST(PagedRender, WhatAPagedModelCannotDoYetIsRefusedInOneLine) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_refusals");
  const fs::path cache = terrain_cache(dir);
  const struct {
    std::string options, says;
  } cases[] = {
      {"--memory 2M --psnr", "full detail"},
      {"--memory 2M --gpu-memory 20K", "--gpu-memory: 0.0 MiB is below"},
      {"--memory 100K", "its first page and its largest group of pages"},
      {"--gpu-memory 8M", "only a cache drawn from its pages"},
  };
  int k = 0;
  for (const auto& c : cases) {
    const fs::path out = dir / ("out" + std::to_string(k++));
    treecut::test::expect_failure(run_treecut("render " + quote(cache) + " " + c.options +
                                              " --frames 2 " + kRun + "-o " + quote(out)),
                                  2, c.says);
    EXPECT_FALSE(fs::exists(out)) << c.options;
  }
}

// The CI case: 2 M points drawn within 32 MiB of node memory and
// 8 MiB of GPU memory, the budgets kept in every frame (stats.csv), pages
// read and copied up as the orbit goes.
TEST(PagedRender, TwoMillionPointsWithin32MiBAnd8MiBOfGpuMemory) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_2m");
  const fs::path cache = terrain_cache(dir, 2000000);
  const treecut::test::CommandResult r =
      render_paged(dir, cache, "--memory 32M --gpu-memory 8M --gpu-upload 1M --frames 60");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = read_csv(dir / "out" / "stats.csv");
  const std::vector<double> ram = column(rows, "pages_resident_mib"),
                            gpu = column(rows, "gpu_resident_mib"),
                            up = column(rows, "gpu_uploaded_kib"),
                            loaded = column(rows, "pages_loaded"),
                            cut = column(rows, "splats_drawn");
  ASSERT_EQ(ram.size(), 60u) << r.out;
  ASSERT_EQ(gpu.size(), 60u) << r.out;
  ASSERT_EQ(up.size(), 60u);
  ASSERT_EQ(loaded.size(), 60u);
  for (std::size_t f = 0; f < 60; ++f) {
    EXPECT_LE(ram[f], 32.0) << "frame " << f;
    EXPECT_LE(gpu[f], 8.0) << "frame " << f;
    // A page past the frame's 1 MiB only when it is the frame's first.
    EXPECT_LE(up[f], 1024.0 + 8192 * 32 / 1024.0) << "frame " << f;
  }
  EXPECT_GT(loaded.back(), 10.0) << "hardly any page read";
  // summary.json says the same peaks, and the frame times' 99th percentile.
  std::ifstream in(dir / "out" / "summary.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_LE(j["counters"]["pages_resident_mib"]["max"].get<double>(), 32.0);
  EXPECT_LE(j["counters"]["gpu_resident_mib"]["max"].get<double>(), 8.0);
  EXPECT_DOUBLE_EQ(j["counters"]["gpu_resident_mib"]["max"].get<double>(),
                   *std::max_element(gpu.begin(), gpu.end()));
  EXPECT_GE(j["p99_frame_ms"].get<double>(), j["median_frame_ms"].get<double>());
  EXPECT_GT(*std::max_element(gpu.begin(), gpu.end()), 1.0) << "hardly any page copied up";
}

// A GPU budget below what the memory budget holds: the memory holds no more
// than the GPU draws (its vertices less a fifth), so the strategy's cut is
// the one drawn: no node stands in for pages that could never go up (with
// the memory at 64 MiB the same flight had up to 16,000 stand-ins and 188
// pages waiting a frame).
TEST(PagedRender, TheMemoryHoldsNoMoreThanTheGpuBudgetDraws) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_gpu_limit");
  const fs::path cache = terrain_cache(dir, 1000000);
  const treecut::test::CommandResult r =
      render_paged(dir, cache, "--memory 64M --gpu-memory 8M --frames 40");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("what the GPU budget draws, not --memory's 64.0 MiB"), std::string::npos)
      << r.out;
  const std::size_t at = r.out.find(" bytes a node");
  ASSERT_NE(at, std::string::npos) << r.out;
  const double node_bytes = std::stod(r.out.substr(r.out.rfind('(', at) + 1));
  const double limit_mib = (8 << 20) / 32 / 5 * 4 * node_bytes / (1 << 20);
  const auto rows = read_csv(dir / "out" / "stats.csv");
  const std::vector<double> ram = column(rows, "pages_resident_mib"),
                            stand_ins = column(rows, "gpu_stand_ins"),
                            waiting = column(rows, "gpu_waiting_pages"),
                            loaded = column(rows, "pages_loaded");
  ASSERT_EQ(ram.size(), 40u) << r.out;
  ASSERT_EQ(stand_ins.size(), 40u);
  for (std::size_t f = 0; f < 40; ++f) {
    EXPECT_LE(ram[f], limit_mib) << "frame " << f;
    EXPECT_EQ(stand_ins[f], 0.0) << "frame " << f;
    EXPECT_EQ(waiting[f], 0.0) << "frame " << f;
  }
  EXPECT_GT(*std::max_element(ram.begin(), ram.end()), limit_mib / 2) << "the limit never reached";
  EXPECT_GE(loaded.back(), 5.0) << "hardly any page read";
}

// A paged model coloured by value (issue 45): each page's nodes coloured
// as they go up to the GPU, no colour per node of the model. A survey tile
// by classification with ground hidden and by intensity over a given
// range: the last frame as the model held whole draws it, and far from the
// file's own colours; the legend lists the classes of the root page's
// nodes, uncounted.
TEST(PagedRender, AColouringByValueIsTheWholeModelsPicture) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_colour");
  ASSERT_EQ(run_treecut("gen survey -n 40000 -o " + quote(dir / "tile")).code, 0);
  const fs::path cache = dir / "tile.tch";
  const treecut::test::CommandResult built =
      run_treecut("build " + quote(dir / "tile") + " -o " + quote(cache));
  ASSERT_EQ(built.code, 0) << built.out;
  const auto last_frame = [&](const std::string& name, const std::string& options) {
    return settled_frame(cache, options + " -s recursive", dir / name);
  };
  const std::string classes = "--color classification --classes -2";
  const std::string intensity = "--color intensity --color-range 300 2000";
  const auto [class_whole, class_whole_out] = last_frame("class_whole", classes);
  const auto [class_paged, class_paged_out] = last_frame("class_paged", classes + " --memory 64M");
  const auto [value_whole, value_whole_out] = last_frame("value_whole", intensity);
  const auto [value_paged, value_paged_out] =
      last_frame("value_paged", intensity + " --memory 64M");
  const auto [own_paged, own_paged_out] = last_frame("own_paged", "--memory 64M");
  for (const treecut::splat::Image* im :
       {&class_whole, &class_paged, &value_whole, &value_paged, &own_paged}) {
    ASSERT_EQ(im->width, 160);
    ASSERT_EQ(im->height, 96);
  }
  const std::size_t pixels = 160 * 96;
  const std::size_t class_off = treecut::test::unmatched_either_way(class_whole, class_paged);
  const std::size_t value_off = treecut::test::unmatched_either_way(value_whole, value_paged);
  const std::size_t own_off = treecut::test::unmatched_either_way(value_paged, own_paged);
  std::printf("unmatched pixels of %zu: classes %zu, intensity %zu, intensity against rgb %zu\n",
              pixels, class_off, value_off, own_off);
  EXPECT_LT(class_off, pixels / 50);
  EXPECT_LT(value_off, pixels / 50);
  EXPECT_GT(own_off, pixels / 20) << "the intensity drawn in the file's own colours";
  EXPECT_NE(class_paged_out.find("colour    classification: 2 ground (hidden), "),
            std::string::npos)
      << class_paged_out;
  EXPECT_EQ(class_paged_out.find('%'), std::string::npos) << class_paged_out;
  EXPECT_NE(value_paged_out.find("intensity: viridis from 300 to 2000"), std::string::npos)
      << value_paged_out;
}

// A scene of caches drawn from their pages (--memory), a generated model held
// whole beside them in the same GPU pool: standing still, the picture of the
// scene held whole.
fs::path paged_scene(const fs::path& dir) {
  terrain_cache(dir);
  treecut::save_cache(treecut::build_from_points(treecut::tools::generate_model(
                          treecut::tools::ModelKind::Sphere, 40000, 2)),
                      {1, 2, 3}, dir / "sphere.tch");
  std::ofstream(dir / "mix.scene") << "treecut-scene 1\n"
                                      "model t terrain.tch\n"
                                      "model s sphere.tch\n"
                                      "generate b building 3 20000\n"
                                      "object t\n"
                                      "object t translate 2.2 0 0\n"
                                      "object s scale 0.6 translate 1.1 2.0 0.3\n"
                                      "object b scale 0.5 0.5 0.8 translate 1.1 -1.5 0\n";
  return dir / "mix.scene";
}

TEST(PagedRender, ASceneOfCachesIsTheWholeScenesPicture) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_scene");
  const fs::path scene = paged_scene(dir);
  const auto last_frame = [&](const std::string& name, const std::string& options) {
    return settled_frame(scene, options + " -s budget", dir / name);
  };
  const auto [whole, whole_out] = last_frame("whole", "");
  const auto [paged, paged_out] = last_frame("paged", "--memory 64M");
  ASSERT_EQ(whole.width, 160);
  ASSERT_EQ(paged.width, 160);
  EXPECT_NE(paged_out.find("pages     2 of 3 models drawn from their pages"), std::string::npos)
      << paged_out;
  EXPECT_EQ(whole_out.find("pages     "), std::string::npos) << whole_out;
  const std::size_t off = treecut::test::unmatched_either_way(whole, paged);
  std::printf("unmatched pixels of %d: %zu\n", 160 * 96, off);
  EXPECT_LT(off, std::size_t{160 * 96 / 100});
}

TEST(PagedRender, ASceneKeepsTinyBudgetsInEveryFrame) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_scene_tiny");
  const fs::path scene = paged_scene(dir);
  for (const char* strategy : {"budget", "recursive"}) {
    SCOPED_TRACE(strategy);
    const fs::path out = dir / strategy;
    const treecut::test::CommandResult r =
        run_treecut("render " + quote(scene) + " --memory 3M --gpu-memory 4M --frames 40 -s " +
                    strategy + " " + kRun + "-o " + quote(out));
    ASSERT_EQ(r.code, 0) << r.out;
    const auto rows = read_csv(out / "stats.csv");
    const std::vector<double> memory = column(rows, "pages_resident_mib");
    const std::vector<double> gpu = column(rows, "gpu_resident_mib");
    const std::vector<double> loaded = column(rows, "pages_loaded");
    ASSERT_EQ(memory.size(), 40u);
    ASSERT_EQ(gpu.size(), 40u);
    ASSERT_FALSE(loaded.empty());
    EXPECT_GT(loaded.back(), 0.0) << "no page was read";
    for (std::size_t f = 0; f < memory.size(); ++f) {
      EXPECT_LE(memory[f], 3.0) << "frame " << f;
      EXPECT_LE(gpu[f], 4.0) << "frame " << f;
    }
  }
  // A GPU budget for a scene with no cache to draw from its pages: refused.
  std::ofstream(dir / "whole.scene") << "treecut-scene 1\ngenerate b building 3 2000\nobject b\n";
  treecut::test::expect_failure(
      run_treecut("render " + quote(dir / "whole.scene") +
                  " --memory 3M --gpu-memory 4M --frames 1 -o " + quote(dir / "refused")),
      2, "--gpu-memory: the scene has no cache");
  EXPECT_FALSE(fs::exists(dir / "refused"));
}

// A scene whose cache has a corrupted page: the page named in one warning
// (the file and the page), the rest of the scene drawn, exit 0.
TEST(PagedRender, ASceneWhoseCacheHasABadPageNamesItAndDrawsTheRest) {
  const fs::path dir = treecut::test::scratch_dir("paged_render_scene_bad_page");
  const fs::path scene = paged_scene(dir);
  {
    std::fstream f(dir / "terrain.tch", std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(0, std::ios::end);
    const auto at = static_cast<std::streamoff>(f.tellg()) - 9;  // the last page's last byte
    char byte = 0;
    f.seekg(at), f.read(&byte, 1);
    byte = static_cast<char>(byte ^ 0x20);
    f.seekp(at), f.write(&byte, 1);
    ASSERT_TRUE(f.good());
  }
  const fs::path out = dir / "out";
  const treecut::test::CommandResult r =
      run_treecut("render " + quote(scene) +
                  " --memory 64M -s budget --frames 4 --warmup 40 --sync --width 160 --height 96 "
                  "-o " +
                  quote(out));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("terrain.tch"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("checksum mismatch (corrupted)"), std::string::npos) << r.out;
  const std::vector<double> failed = column(read_csv(out / "stats.csv"), "pages_failed");
  ASSERT_FALSE(failed.empty());
  EXPECT_EQ(failed.back(), 1.0);
  const treecut::splat::Image last = treecut::test::load_png(out / "frame_00003.png");
  ASSERT_EQ(last.width, 160);
  std::size_t drawn = 0;
  for (std::size_t i = 0; i < last.rgba.size(); i += 4)
    drawn += last.rgba[i] != last.rgba[0] || last.rgba[i + 1] != last.rgba[1];
  EXPECT_GT(drawn, std::size_t{160 * 96 / 10}) << "the rest of the scene was not drawn";
}

#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#include <stb/stb_image.h>
