// `treecut view` opens another model without restarting: the script command
// `open FILE` (the path the window's drag and drop, the O key and the HUD
// field take too) under Xvfb. The screenshot after `open` shows the other
// model: it is close to a run that started with that model and far from the
// one before the open. A missing model fails before the window opens, a
// malformed one when it is loaded, each with one line naming the file, exit 2.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "image_compare.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
using treecut::splat::Image;
using treecut::test::load_png;
using treecut::test::quote;

constexpr int kWidth = 960;
constexpr int kHeight = 480;

bool have_xvfb() {
  return std::system("command -v xvfb-run > /dev/null 2>&1") == 0;
}

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << p;
}

// `treecut view ARGS` in a window under Xvfb, caches in `dir`; no frame-rate
// control (the default 30 fps would size the cuts by this machine's load).
treecut::test::CommandResult view(const fs::path& dir, const std::string& args) {
  auto r = treecut::test::run_treecut_in_xvfb(
      "view --width " + std::to_string(kWidth) + " --height " + std::to_string(kHeight) +
          " --target-fps 0 --screenshot-dir " + quote(dir) + " " + args,
      dir, "1280x800x24", "XDG_CACHE_HOME=" + quote(dir / "cache"));
  return r ? *r : treecut::test::CommandResult{-1, "xvfb-run is not installed"};
}

// Share of pixels of the right half (the HUD sits top left) that differ by
// more than 24 in a channel.
double right_half_difference(const Image& a, const Image& b) {
  std::size_t differ = 0, all = 0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = a.width / 2; x < a.width; ++x) {
      const std::size_t i = (std::size_t(y) * std::size_t(a.width) + std::size_t(x)) * 4;
      bool d = false;
      for (int c = 0; c < 3; ++c) d |= std::abs(int(a.rgba[i + c]) - int(b.rgba[i + c])) > 24;
      differ += d;
      ++all;
    }
  }
  return double(differ) / double(all);
}

std::size_t lines_of(const std::string& out, const std::string& needle) {
  std::size_t n = 0;
  std::size_t pos = 0;
  while (pos < out.size()) {
    const std::size_t end = out.find('\n', pos);
    const std::string line = out.substr(pos, end - pos);
    n += line.find(needle) != std::string::npos;
    if (end == std::string::npos) break;
    pos = end + 1;
  }
  return n;
}

class ViewerOpen : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_xvfb()) GTEST_SKIP() << "xvfb-run not found (apt install xvfb)";
    // One folder per test: ctest runs the tests of this file as parallel processes.
    dir_ =
        treecut::test::scratch_dir(std::string("viewer_open/") +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    for (const auto& [kind, file] : {std::pair{"sphere", "a.ply"}, std::pair{"terrain", "b.ply"}}) {
      const auto r = treecut::test::run_treecut(std::string("gen ") + kind + " -n 20000 -o " +
                                                quote(dir_ / file));
      ASSERT_EQ(r.code, 0) << r.out;
    }
  }
  fs::path dir_;
};

TEST_F(ViewerOpen, TheScreenshotAfterOpenShowsTheOtherModel) {
  write_file(dir_ / "open.script",
             "treecut-view-script 1\nconverge 200\nscreenshot before.png\nopen b.ply\n"
             "converge 200\nscreenshot after.png\nexit\n");
  write_file(dir_ / "direct.script",
             "treecut-view-script 1\nconverge 200\nscreenshot direct.png\nexit\n");
  const auto opened =
      view(dir_, quote(dir_ / "a.ply") + " --script " + quote(dir_ / "open.script"));
  ASSERT_EQ(opened.code, 0) << opened.out;
  EXPECT_NE(opened.out.find("opened b.ply"), std::string::npos) << opened.out;
  const auto direct =
      view(dir_, quote(dir_ / "b.ply") + " --script " + quote(dir_ / "direct.script"));
  ASSERT_EQ(direct.code, 0) << direct.out;

  const Image before = load_png(dir_ / "before.png");
  const Image after = load_png(dir_ / "after.png");
  const Image b_alone = load_png(dir_ / "direct.png");
  for (const Image* im : {&before, &after, &b_alone}) {
    ASSERT_EQ(im->width, kWidth);
    ASSERT_EQ(im->height, kHeight);
  }
  const double changed = right_half_difference(before, after);
  const double from_b = right_half_difference(after, b_alone);
  std::printf("right half: %.3f of pixels changed by open, %.3f differ from b.ply alone\n", changed,
              from_b);
  EXPECT_GT(changed, 0.05) << "the open did not change the view";
  EXPECT_LT(from_b, changed / 4) << "after open the window does not show b.ply";
}

// A model drawn from its pages coloured anew in the window: the pages on
// the GPU are written again in the new colours (GpuNodePool::prepare), and
// back in the file's own when the colouring is undone.
TEST_F(ViewerOpen, APagedModelIsColouredAnewInTheWindow) {
  ASSERT_EQ(treecut::test::run_treecut("gen survey -n 40000 -o " + quote(dir_ / "tile")).code, 0);
  const auto built = treecut::test::run_treecut("build " + quote(dir_ / "tile") + " -o " +
                                                quote(dir_ / "tile.tch"));
  ASSERT_EQ(built.code, 0) << built.out;
  write_file(dir_ / "colour.script",
             "treecut-view-script 1\nconverge 200\nscreenshot own.png\ncolor classification\n"
             "converge 200\nscreenshot classes.png\ncolor rgb\nconverge 200\n"
             "screenshot back.png\nexit\n");
  const auto v = view(
      dir_, quote(dir_ / "tile.tch") + " --memory 64M --script " + quote(dir_ / "colour.script"));
  ASSERT_EQ(v.code, 0) << v.out;
  EXPECT_EQ(v.out.find("colours: rgb"), std::string::npos) << "fell back to rgb: " << v.out;
  const Image own = load_png(dir_ / "own.png"), classes = load_png(dir_ / "classes.png"),
              back = load_png(dir_ / "back.png");
  for (const Image* im : {&own, &classes, &back}) ASSERT_EQ(im->width, kWidth);
  const double recoloured = right_half_difference(own, classes);
  const double undone = right_half_difference(own, back);
  std::printf("right half: %.3f of pixels changed by the colouring, %.3f after undoing it\n",
              recoloured, undone);
  EXPECT_GT(recoloured, 0.05) << "the pages up kept their colours";
  EXPECT_LT(undone, recoloured / 4) << "the file's colours did not come back";
}

// A scene whose models are caches, drawn from their pages in the window
// (its GPU pool shared by its models) and coloured anew there.
TEST_F(ViewerOpen, ASceneOfCachesIsDrawnFromItsPagesInTheWindow) {
  for (const char* kind : {"terrain", "sphere"}) {
    const fs::path ply = dir_ / (std::string(kind) + ".ply");
    ASSERT_EQ(
        treecut::test::run_treecut(std::string("gen ") + kind + " -n 40000 -o " + quote(ply)).code,
        0);
    const auto built = treecut::test::run_treecut("build " + quote(ply) + " -o " +
                                                  quote(dir_ / (std::string(kind) + ".tch")));
    ASSERT_EQ(built.code, 0) << built.out;
  }
  write_file(dir_ / "two.scene",
             "treecut-scene 1\nmodel t terrain.tch\nmodel s sphere.tch\nobject t\n"
             "object s scale 0.5 translate 0 0 0.8\n");
  write_file(dir_ / "scene.script",
             "treecut-view-script 1\nconverge 200\nscreenshot own.png\ncolor elevation\n"
             "converge 200\nscreenshot elevation.png\nexit\n");
  const auto v = view(dir_, quote(dir_ / "two.scene") + " --memory 64M --gpu-memory 32M --script " +
                                quote(dir_ / "scene.script"));
  ASSERT_EQ(v.code, 0) << v.out;
  const Image own = load_png(dir_ / "own.png"), elevation = load_png(dir_ / "elevation.png");
  ASSERT_EQ(own.width, kWidth);
  ASSERT_EQ(elevation.width, kWidth);
  const double recoloured = right_half_difference(own, elevation);
  std::printf("right half: %.3f of pixels changed by the colouring\n", recoloured);
  EXPECT_GT(recoloured, 0.05) << "the scene's pages kept their colours";
}

TEST_F(ViewerOpen, AMissingModelFailsBeforeTheWindowWithOneLine) {
  write_file(dir_ / "missing.script", "treecut-view-script 1\nframes 2\nopen missing.ply\nexit\n");
  // Checked with the script, before a window (or a display) is needed.
  const auto v = treecut::test::run_treecut("view " + quote(dir_ / "a.ply") + " --script " +
                                            quote(dir_ / "missing.script"));
  EXPECT_EQ(v.code, 2) << v.out;
  EXPECT_EQ(lines_of(v.out, ""), 1u) << v.out;
  EXPECT_NE(v.out.find((dir_ / "missing.ply").string()), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("missing.script:3: open"), std::string::npos) << v.out;
}

TEST_F(ViewerOpen, AMalformedModelFailsTheScriptWhenItLoadsWithOneLine) {
  write_file(dir_ / "bad.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
             "property float y\nproperty float z\nend_header\n0 0 0\n1 1\n");
  write_file(dir_ / "bad.script",
             "treecut-view-script 1\nframes 2\nopen bad.ply\nscreenshot never.png\nexit\n");
  const auto r = view(dir_, quote(dir_ / "a.ply") + " --script " + quote(dir_ / "bad.script"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(lines_of(r.out, "treecut:"), 1u) << r.out;
  EXPECT_EQ(lines_of(r.out, (dir_ / "bad.ply").string()), 1u) << r.out;
  EXPECT_FALSE(fs::exists(dir_ / "never.png")) << "the script went on after the failed open";
}

// Issue 30, tested as a person would: a square 0.5 in front of a larger one,
// face on in the window. Eye-dome lighting darkens the back square along the
// front one's edge and leaves the middle; a clip box at x = 0 removes the
// left half's pixels; two picks 80 pixels apart on the front square measure
// the 80 pixels' worth of distance (0.345 units at its depth).
TEST_F(ViewerOpen, EyeDomeClipAndMeasureInTheWindow) {
  std::string ply;
  std::size_t n = 0;
  std::string body;
  for (const auto& [half, z] : {std::pair{0.8, -0.5}, std::pair{0.3, 0.0}}) {
    const int steps = int(std::lround(2 * half / 0.01));
    for (int i = 0; i <= steps; ++i) {
      for (int j = 0; j <= steps; ++j) {
        body += std::to_string(-half + 0.01 * i) + " " + std::to_string(-half + 0.01 * j) + " " +
                std::to_string(z) + " 0 0 1 200 200 200\n";
        ++n;
      }
    }
  }
  write_file(dir_ / "squares.ply",
             "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
                 "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n"
                 "property float ny\nproperty float nz\nproperty uchar red\nproperty uchar "
                 "green\nproperty uchar blue\nend_header\n" +
                 body);
  write_file(dir_ / "face.campath",
             "treecut-camera-path 1\n0 0 0 2.5 0 0 0 0 1 0 45\n1 0 0 2.5 0 0 0 0 1 0 45\n");
  write_file(dir_ / "tools.script",
             "treecut-view-script 1\nplay face.campath\nconverge 300\nframes 3\n"
             "screenshot plain.png\nedl on\nframes 2\nscreenshot edl.png\nedl off\n"
             "clip 0 -1 -1 1 1 1\nframes 2\nscreenshot clip.png\nclip off\n"
             "pick 440 240\npick 520 240\nexit\n");
  const auto r =
      view(dir_, quote(dir_ / "squares.ply") + " --mode fast --edl off --points 100000 --script " +
                     quote(dir_ / "tools.script"));
  ASSERT_EQ(r.code, 0) << r.out;
  const Image plain = load_png(dir_ / "plain.png"), edl = load_png(dir_ / "edl.png"),
              clip = load_png(dir_ / "clip.png");
  ASSERT_EQ(plain.width, kWidth);
  const auto red = [](const Image& im, int x, int y) {
    return int(im.rgba[(std::size_t(y) * std::size_t(im.width) + std::size_t(x)) * 4]);
  };
  const int cx = kWidth / 2, cy = kHeight / 2;
  // The front square's edge: 0.3 / (2.5 tan 22.5 deg) of the half height.
  const int edge = int(0.3 / (2.5 * std::tan(0.3927)) * kHeight / 2.0);
  EXPECT_NEAR(red(edl, cx, cy), red(plain, cx, cy), 3) << "the middle keeps its colour";
  int darker = 0;
  for (int x = cx + edge - 4; x <= cx + edge + 4; ++x) {
    darker += red(edl, x, cy) + 40 < red(plain, x, cy) ? 1 : 0;
  }
  EXPECT_GE(darker, 1) << "EDL darkens the back square along the front one's edge";
  // Clipped to x >= 0: nothing left of the middle but the background.
  const int background = red(plain, 4, 4);
  int drawn_left = 0, drawn_right = 0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < cx - 8; ++x) drawn_left += std::abs(red(clip, x, y) - background) > 3;
    for (int x = cx + 8; x < kWidth; ++x) drawn_right += std::abs(red(clip, x, y) - background) > 3;
  }
  EXPECT_EQ(drawn_left, 0);
  EXPECT_GT(drawn_right, 10000);
  // The measure line: 80 pixels at depth 2.5 (2 * 2.5 * tan(22.5 deg) / 480 a pixel).
  const auto at = r.out.find("measure   distance ");
  ASSERT_NE(at, std::string::npos) << r.out;
  const double distance = std::strtod(r.out.c_str() + at + 19, nullptr);
  const double want = 80.0 * 2.0 * 2.5 * std::tan(0.3927) / kHeight;
  EXPECT_NEAR(distance, want, 0.03 * want) << r.out;
}

}  // namespace

#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#include <stb/stb_image.h>
