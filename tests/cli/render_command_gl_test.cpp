// `treecut render` as a user runs it: headless (EGL or OSMesa) on a generated model,
// N PNG frames, stats.csv with the columns docs/rendering.md documents, a
// finite PSNR with --psnr, summary.json and plot.svg; bad input exits with 2
// and leaves no output folder behind.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, sep)) fields.push_back(field);
  if (!line.empty() && line.back() == sep) fields.emplace_back();
  return fields;
}

// The stats.csv header as docs/rendering.md documents it: the backquoted list
// after "`stats.csv`: ", spaces and line breaks removed.
std::string documented_stats_header() {
  const std::string doc = read_text(fs::path(TREECUT_SOURCE_DIR) / "docs" / "rendering.md");
  const std::string key = "`stats.csv`: `";
  const auto at = doc.find(key);
  if (at == std::string::npos) return {};
  const auto end = doc.find('`', at + key.size());
  std::string header;
  for (char c : doc.substr(at + key.size(), end - at - key.size())) {
    if (c != ' ' && c != '\n') header += c;
  }
  return header;
}

// Width and height from a PNG's IHDR chunk; {0, 0} if it is not a PNG.
std::pair<unsigned, unsigned> png_size(const fs::path& p) {
  const std::string b = read_text(p);
  if (b.size() < 24 || b.compare(0, 8, "\x89PNG\r\n\x1a\n") != 0 || b.compare(12, 4, "IHDR") != 0) {
    return {0, 0};
  }
  auto be32 = [&](std::size_t i) {
    return unsigned(static_cast<unsigned char>(b[i])) << 24 |
           unsigned(static_cast<unsigned char>(b[i + 1])) << 16 |
           unsigned(static_cast<unsigned char>(b[i + 2])) << 8 |
           unsigned(static_cast<unsigned char>(b[i + 3]));
  };
  return {be32(16), be32(20)};
}

double number(const std::string& s) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  return !s.empty() && end == s.c_str() + s.size() ? v : std::nan("");
}

// A small generated model, a small frame, a budget well below the leaves (so
// the LOD frame differs from full detail and the PSNR is finite), the stage
// run synchronously.
const std::string kSmallRun =
    "render --default-kind sphere --default-points 6000 --width 160 --height 96 --warmup 3 "
    "--sync -p max_nodes=600 ";

// A tick label as a number ("2.5", "200 k", "1.5 M").
double tick_value(const std::string& label) {
  const double scale = label.ends_with(" M") ? 1e6 : label.ends_with(" k") ? 1e3 : 1.0;
  return number(scale == 1.0 ? label : label.substr(0, label.size() - 2)) * scale;
}

// The ticks of one axis step by 1, 2 or 5 times a power of ten.
void expect_one_two_five(const std::vector<double>& ticks, const std::string& what) {
  ASSERT_GE(ticks.size(), 2u) << what;
  const double step = ticks[1] - ticks[0];
  const double mantissa = step / std::pow(10.0, std::floor(std::log10(step) + 1e-9));
  EXPECT_TRUE(std::abs(mantissa - 1) < 1e-6 || std::abs(mantissa - 2) < 1e-6 ||
              std::abs(mantissa - 5) < 1e-6)
      << what << ": step " << step;
  for (std::size_t i = 1; i < ticks.size(); ++i) {
    EXPECT_NEAR(ticks[i] - ticks[i - 1], step, step * 1e-6) << what;
  }
}

// Issue 30: plot.svg has the panels named, 1-2-5 ticks on both axes, a
// legend per panel naming every strategy, and no line on a panel's frame.
void check_plot(const std::string& svg, const std::vector<std::string>& panels,
                std::size_t strategies) {
  const std::regex panel_start("<g class=\"panel\" id=\"([a-z_]+)\">");
  std::vector<std::string> ids;
  std::vector<std::size_t> at;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), panel_start);
       it != std::sregex_iterator(); ++it) {
    ids.push_back((*it)[1]);
    at.push_back(static_cast<std::size_t>(it->position()));
  }
  EXPECT_EQ(ids, panels);
  at.push_back(svg.size());
  const std::regex frame(
      "<rect class=\"frame\" x=\"([0-9.]+)\" y=\"([0-9.]+)\" width=\"([0-9.]+)\" "
      "height=\"([0-9.]+)\"");
  const std::regex ytick("class=\"ytick\"[^>]*>([^<]+)<");
  const std::regex xtick("class=\"xtick\"[^>]*>([^<]+)<");
  const std::regex points("points=\"([^\"]*)\"");
  const std::regex legend("class=\"legend-entry\"");
  for (std::size_t p = 0; p + 1 < at.size(); ++p) {
    const std::string part = svg.substr(at[p], at[p + 1] - at[p]);
    std::smatch m;
    ASSERT_TRUE(std::regex_search(part, m, frame)) << ids[p];
    const double x0 = number(m[1]), y0 = number(m[2]), w = number(m[3]), h = number(m[4]);
    for (const auto* re : {&ytick, &xtick}) {
      std::vector<double> ticks;
      for (auto it = std::sregex_iterator(part.begin(), part.end(), *re);
           it != std::sregex_iterator(); ++it) {
        ticks.push_back(tick_value((*it)[1]));
      }
      expect_one_two_five(ticks, ids[p] + (re == &ytick ? " y" : " x"));
    }
    std::size_t lines = 0;
    for (auto it = std::sregex_iterator(part.begin(), part.end(), points);
         it != std::sregex_iterator(); ++it, ++lines) {
      std::istringstream pts((*it)[1].str());
      double x = 0, y = 0;
      char comma = 0;
      while (pts >> x >> comma >> y) {
        EXPECT_TRUE(x > x0 + 1 && x < x0 + w - 1 && y > y0 + 1 && y < y0 + h - 1)
            << ids[p] << ": (" << x << ", " << y << ") on or past the frame";
      }
    }
    EXPECT_GE(lines, strategies) << ids[p];
    EXPECT_EQ(std::size_t(std::distance(std::sregex_iterator(part.begin(), part.end(), legend),
                                        std::sregex_iterator())),
              strategies)
        << ids[p];
  }
}

}  // namespace

TEST(RenderCommand, WritesFramesStatsSummaryAndAFinitePsnr) {
  const fs::path dir = treecut::test::scratch_dir("render_command") / "out";
  constexpr int kFrames = 5;
  const treecut::test::CommandResult r =
      treecut::test::run_treecut(kSmallRun + "--frames " + std::to_string(kFrames) + " --psnr -o " +
                                 treecut::test::quote(dir));
  ASSERT_EQ(r.code, 0) << r.out;

  // N PNG frames of the requested size, and nothing else named frame_*.
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().filename().string().rfind("frame_", 0) == 0) ++pngs;
  }
  EXPECT_EQ(pngs, kFrames);
  for (int f = 0; f < kFrames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.png", f);
    const auto [w, h] = png_size(dir / name);
    EXPECT_EQ(w, 160u) << name;
    EXPECT_EQ(h, 96u) << name;
  }

  // stats.csv: the documented header, then one row per frame.
  const std::string expected_header = documented_stats_header();
  ASSERT_FALSE(expected_header.empty()) << "docs/rendering.md lost the stats.csv columns";
  std::ifstream csv(dir / "stats.csv");
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line, expected_header);
  const std::size_t columns = split(expected_header, ',').size();
  const std::vector<std::string> names = split(expected_header, ',');
  auto column = [&](const char* name) {
    return std::size_t(std::find(names.begin(), names.end(), name) - names.begin());
  };
  int rows = 0;
  while (std::getline(csv, line)) {
    const std::vector<std::string> f = split(line, ',');
    ASSERT_EQ(f.size(), columns) << line;
    EXPECT_EQ(number(f[column("frame")]), double(rows)) << line;
    EXPECT_GT(number(f[column("frame_ms")]), 0.0) << line;
    // Two figures with two names: the splats drawn (cut nodes) and the input
    // points they represent (the leaves under them), never fewer.
    const double cut = number(f[column("splats_drawn")]);
    EXPECT_GT(cut, 0.0) << line;
    EXPECT_LE(cut, 600.0) << line;
    EXPECT_GE(number(f[column("points_represented")]), cut) << line;
    const double psnr = number(f[column("psnr_db")]);
    EXPECT_TRUE(std::isfinite(psnr)) << "psnr_db '" << f[column("psnr_db")] << "'";
    EXPECT_GT(psnr, 5.0) << line;
    ++rows;
  }
  EXPECT_EQ(rows, kFrames);

  // The summary and the printed line carry the PSNR too.
  const std::string summary = read_text(dir / "summary.json");
  EXPECT_NE(summary.find("\"frames\": " + std::to_string(kFrames)), std::string::npos) << summary;
  EXPECT_EQ(summary.find("\"mean_psnr_db\": null"), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"mean_psnr_db\": "), std::string::npos) << summary;
  EXPECT_NE(r.out.find(" dB"), std::string::npos) << r.out;
  check_plot(read_text(dir / "plot.svg"), {"frame_time", "splats", "psnr"}, 1);

  // Two strategies without --psnr: two panels, each with a legend of both.
  const fs::path two = dir.parent_path() / "two";
  ASSERT_EQ(treecut::test::run_treecut(kSmallRun +
                                       "--frames 3 --no-png -s optimization -s "
                                       "recursive -o " +
                                       treecut::test::quote(two))
                .code,
            0);
  check_plot(read_text(two / "plot.svg"), {"frame_time", "splats"}, 2);
}

// Both headless back ends (--gl): an EGL device (here Mesa's software one)
// and OSMesa, both llvmpipe on this machine, draw the same frames; each
// report names its renderer and back end.
TEST(RenderCommand, BothHeadlessBackEndsDrawTheSameFramesAndSaySo) {
  const fs::path scratch = treecut::test::scratch_dir("render_command_gl");
  std::string frames[2];
  const char* backends[2] = {"egl", "osmesa"};
  for (int i = 0; i < 2; ++i) {
    const fs::path dir = scratch / backends[i];
    const treecut::test::CommandResult r = treecut::test::run_treecut(
        kSmallRun + "--frames 2 --gl " + backends[i] + " -o " + treecut::test::quote(dir));
    ASSERT_EQ(r.code, 0) << backends[i] << "\n" << r.out;
    const std::string tag = std::string("(") + backends[i];
    const auto line = r.out.find("renderer  ");
    ASSERT_NE(line, std::string::npos) << r.out;
    EXPECT_NE(r.out.substr(line, r.out.find('\n', line) - line).find(tag), std::string::npos)
        << r.out;
    const auto summary = nlohmann::json::parse(read_text(dir / "summary.json"));
    EXPECT_NE(summary.at("renderer").get<std::string>().find(tag), std::string::npos)
        << summary.dump();
    frames[i] = read_text(dir / "frame_00001.png");
    EXPECT_FALSE(frames[i].empty()) << backends[i];
  }
  EXPECT_TRUE(frames[0] == frames[1]) << "EGL's and OSMesa's llvmpipe drew different frames";
}

TEST(RenderCommand, NoPngWritesStatisticsOnly) {
  const fs::path dir = treecut::test::scratch_dir("render_command_nopng") / "out";
  const treecut::test::CommandResult r =
      treecut::test::run_treecut(kSmallRun + "--frames 3 --no-png -o " + treecut::test::quote(dir));
  ASSERT_EQ(r.code, 0) << r.out;
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_NE(e.path().extension(), ".png") << e.path();
  }
  std::ifstream csv(dir / "stats.csv");
  std::string line;
  int lines = 0;
  while (std::getline(csv, line)) ++lines;
  EXPECT_EQ(lines, 1 + 3);
}

// The query columns of stats.csv and the queries block of summary.json, from
// a strategy that posts queries (tests/querying_plugin.cpp: each iteration a
// request about each child of the root, and one about the root; --sync: one
// iteration per frame) and from one that posts none (all zeros).
TEST(RenderCommand, StatsAndSummaryCountTheStrategysQueries) {
  const fs::path dir = treecut::test::scratch_dir("render_command_queries") / "out";
  constexpr int kFrames = 12;
  const treecut::test::CommandResult r = treecut::test::run_treecut(
      "render --default-kind sphere --default-points 6000 --width 160 --height 96 --warmup 3 "
      "--sync --no-png --frames " +
      std::to_string(kFrames) + " --plugin " + treecut::test::quote(TREECUT_QUERYING_PLUGIN) +
      " -s querying -o " + treecut::test::quote(dir));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("queries   querying: "), std::string::npos) << r.out;

  std::ifstream csv(dir / "stats.csv");
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line, documented_stats_header());
  const std::vector<std::string> names = split(line, ',');
  auto column = [&](const char* name) {
    const auto at = std::size_t(std::find(names.begin(), names.end(), name) - names.begin());
    EXPECT_LT(at, names.size()) << name;
    return at;
  };
  double issued = 0, answered = 0, latency_max = 0;
  int rows = 0;
  while (std::getline(csv, line)) {
    const std::vector<std::string> f = split(line, ',');
    ASSERT_EQ(f.size(), names.size()) << line;
    const double i = number(f[column("queries_issued")]);
    const double a = number(f[column("queries_answered")]);
    const double pending = number(f[column("queries_pending")]);
    const double mean = number(f[column("query_latency_frames_mean")]);
    const double max = number(f[column("query_latency_frames_max")]);
    EXPECT_GE(i, 0.0) << line;
    EXPECT_GE(pending, 0.0) << line;
    EXPECT_GE(number(f[column("query_cpu_us")]), 0.0) << line;
    if (a > 0) {
      // Answers come frames later, never in the frame that asked.
      EXPECT_GE(mean, 1.0) << line;
      EXPECT_GE(max, mean) << line;
    } else {
      EXPECT_EQ(mean, 0.0) << line;
      EXPECT_EQ(max, 0.0) << line;
    }
    issued += i;
    answered += a;
    latency_max = std::max(latency_max, max);
    ++rows;
  }
  EXPECT_EQ(rows, kFrames);
  EXPECT_GT(issued, double(kFrames));  // the children of the root and the root, most frames
  EXPECT_GT(answered, 0.0);

  // The totals cover the warm-up too: at least what the rows add up to.
  const nlohmann::json j = nlohmann::json::parse(read_text(dir / "summary.json"));
  ASSERT_TRUE(j.contains("queries")) << j.dump();
  const nlohmann::json& q = j["queries"];
  EXPECT_GE(q["issued"].get<double>(), issued);
  EXPECT_GE(q["answered"].get<double>(), answered);
  // Every proxy issued is answered or pending (answered also counts requests
  // answered without the GPU: an eye inside the node's sphere).
  EXPECT_LE(q["pending"].get<double>(), q["issued"].get<double>());
  EXPECT_GE(q["answered"].get<double>() + q["pending"].get<double>(), q["issued"].get<double>());
  EXPECT_GE(q["latency_frames_mean"].get<double>(), 1.0);
  EXPECT_GE(q["latency_frames_max"].get<double>(), latency_max);
  EXPECT_EQ(q["frames"].get<int>(), 3 + kFrames);
  EXPECT_GT(q["batches"].get<double>(), 0.0);

  // A strategy that posts none: the same columns, all zeros but the CPU time
  // of an idle executor.
  const fs::path none = treecut::test::scratch_dir("render_command_no_queries") / "out";
  const treecut::test::CommandResult r0 = treecut::test::run_treecut(
      kSmallRun + "--frames 3 --no-png -o " + treecut::test::quote(none));
  ASSERT_EQ(r0.code, 0) << r0.out;
  EXPECT_EQ(r0.out.find("queries   "), std::string::npos) << r0.out;
  std::ifstream csv0(none / "stats.csv");
  ASSERT_TRUE(std::getline(csv0, line));
  EXPECT_EQ(line, documented_stats_header());
  while (std::getline(csv0, line)) {
    const std::vector<std::string> f = split(line, ',');
    ASSERT_EQ(f.size(), names.size()) << line;
    for (const char* c : {"queries_issued", "queries_answered", "queries_pending",
                          "query_latency_frames_mean", "query_latency_frames_max"}) {
      EXPECT_EQ(number(f[column(c)]), 0.0) << c << ": " << line;
    }
  }
  const nlohmann::json j0 = nlohmann::json::parse(read_text(none / "summary.json"));
  EXPECT_EQ(j0["queries"]["issued"].get<int>(), 0);
  EXPECT_EQ(j0["queries"]["answered"].get<int>(), 0);
}

TEST(RenderCommand, BadInputExitsWithTwoAndWritesNothing) {
  const fs::path scratch = treecut::test::scratch_dir("render_command_bad");
  const fs::path bad_ply = scratch / "bad.ply";
  std::ofstream(bad_ply)
      << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n"
         "1\n";  // two rows missing
  const fs::path bad_path = scratch / "bad.path";
  std::ofstream(bad_path) << "not a camera path\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"unknown strategy", "-s no-such-strategy"},
      {"unknown parameter", "-p no_such_param=1"},
      {"parameter out of range", "-p max_nodes=0"},
      {"unknown splat mode", "--mode glossy"},
      {"unknown GL back end", "--gl vulkan"},
      {"zero frames", "--frames 0"},
      {"missing model", treecut::test::quote(scratch / "missing.ply")},
      {"malformed model", treecut::test::quote(bad_ply)},
      {"malformed camera path", "--path " + treecut::test::quote(bad_path)},
  };
  for (const auto& [what, args] : cases) {
    const fs::path out = scratch / "out";
    const treecut::test::CommandResult r = treecut::test::run_treecut(
        "render --default-points 2000 --width 64 --height 48 --frames 2 --warmup 0 " + args +
        " -o " + treecut::test::quote(out));
    EXPECT_EQ(r.code, 2) << what << "\n" << r.out;
    EXPECT_FALSE(fs::exists(out)) << what << ": wrote " << out;
  }
}
