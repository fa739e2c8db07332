// `treecut view` opens another model without restarting: the script command
// `open FILE` (the path the window's drag and drop, the O key and the HUD
// field take too) under Xvfb. The screenshot after `open` shows the other
// model: it is close to a run that started with that model and far from the
// one before the open. A missing model fails before the window opens, a
// malformed one when it is loaded, each with one line naming the file, exit 2.
#include <gtest/gtest.h>
#include <stb/stb_image.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
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

// `treecut view ARGS` in a window under Xvfb, caches in `dir`.
treecut::test::CommandResult view(const fs::path& dir, const std::string& args) {
  auto r = treecut::test::run_treecut_in_xvfb(
      "view --width " + std::to_string(kWidth) + " --height " + std::to_string(kHeight) +
          " --screenshot-dir " + quote(dir) + " " + args,
      dir, "1280x800x24", "XDG_CACHE_HOME=" + quote(dir / "cache"));
  return r ? *r : treecut::test::CommandResult{-1, "xvfb-run is not installed"};
}

struct Rgb {
  int w = 0, h = 0;
  std::vector<unsigned char> px;  // RGB
};

Rgb load(const fs::path& png) {
  Rgb im;
  int n = 0;
  unsigned char* data = stbi_load(png.c_str(), &im.w, &im.h, &n, 3);
  if (data == nullptr) return im;
  im.px.assign(data, data + std::size_t(im.w) * std::size_t(im.h) * 3);
  stbi_image_free(data);
  return im;
}

// Share of pixels of the right half (the HUD sits top left) that differ by
// more than 24 in a channel.
double right_half_difference(const Rgb& a, const Rgb& b) {
  std::size_t differ = 0, all = 0;
  for (int y = 0; y < a.h; ++y) {
    for (int x = a.w / 2; x < a.w; ++x) {
      const std::size_t i = (std::size_t(y) * std::size_t(a.w) + std::size_t(x)) * 3;
      bool d = false;
      for (int c = 0; c < 3; ++c) d |= std::abs(int(a.px[i + c]) - int(b.px[i + c])) > 24;
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

  const Rgb before = load(dir_ / "before.png");
  const Rgb after = load(dir_ / "after.png");
  const Rgb b_alone = load(dir_ / "direct.png");
  for (const Rgb* im : {&before, &after, &b_alone}) {
    ASSERT_EQ(im->w, kWidth);
    ASSERT_EQ(im->h, kHeight);
  }
  const double changed = right_half_difference(before, after);
  const double from_b = right_half_difference(after, b_alone);
  std::printf("right half: %.3f of pixels changed by open, %.3f differ from b.ply alone\n", changed,
              from_b);
  EXPECT_GT(changed, 0.05) << "the open did not change the view";
  EXPECT_LT(from_b, changed / 4) << "after open the window does not show b.ply";
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

}  // namespace

#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#include <stb/stb_image.h>
