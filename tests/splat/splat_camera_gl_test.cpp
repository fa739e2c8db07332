// Tests of the renderer's non-GL parts: cameras, camera paths and image
// metrics (the target-frame-rate governor: frame_rate_gl_test.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <limits>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/image.hpp"

namespace treecut::splat {
namespace {

constexpr const char* kPath =
    "treecut-camera-path 1\n"
    "# time eye target up fov\n"
    "0 0 0 5  0 0 0  0 1 0  40\n"
    "\n"
    "2 10 0 5  0 0 0  0 1 0  60\n";

TEST(CameraPath, ParsesAndInterpolatesLinearly) {
  const CameraPath p = parse_camera_path(kPath, "test");
  ASSERT_EQ(p.keys.size(), 2u);
  EXPECT_DOUBLE_EQ(p.duration(), 2.0);
  const Camera mid = p.at(1.0);
  EXPECT_FLOAT_EQ(mid.eye.x, 5.0f);
  EXPECT_FLOAT_EQ(mid.fov_y_deg, 50.0f);
  // Clamped outside the path.
  EXPECT_FLOAT_EQ(p.at(-1.0).eye.x, 0.0f);
  EXPECT_FLOAT_EQ(p.at(99.0).eye.x, 10.0f);
}

TEST(CameraPath, FormatRoundTrips) {
  const CameraPath p = parse_camera_path(kPath, "test");
  const CameraPath q = parse_camera_path(format_camera_path(p), "again");
  ASSERT_EQ(q.keys.size(), p.keys.size());
  for (std::size_t i = 0; i < p.keys.size(); ++i) {
    EXPECT_DOUBLE_EQ(q.keys[i].time, p.keys[i].time);
    EXPECT_EQ(q.keys[i].camera.eye, p.keys[i].camera.eye);
    EXPECT_EQ(q.keys[i].camera.target, p.keys[i].camera.target);
    EXPECT_EQ(q.keys[i].camera.fov_y_deg, p.keys[i].camera.fov_y_deg);
  }
}

TEST(CameraPath, FileRoundTrips) {
  const auto dir = test::scratch_dir("camera_path_file");
  const CameraPath p = orbit_path({-1, -1, -1}, {1, 1, 1}, 1.5f, 4.0, 9);
  save_camera_path(dir / "orbit.campath", p);
  const CameraPath q = load_camera_path(dir / "orbit.campath");
  ASSERT_EQ(q.keys.size(), 9u);
  EXPECT_NEAR(glm::length(q.keys[4].camera.eye - p.keys[4].camera.eye), 0.0f, 1e-5f);
  EXPECT_THROW(load_camera_path(dir / "missing.campath"), InputError);
}

TEST(CameraPath, RejectsEveryMalformedLine) {
  const char* bad[] = {
      "",                                                                         // no header
      "treecut-camera-path 2\n0 0 0 5 0 0 0 0 1 0 40\n",                          // wrong version
      "treecut-camera-path 1\n",                                                  // no keys
      "treecut-camera-path 1\n0 0 0 5 0 0 0 0 1 0\n",                             // 10 numbers
      "treecut-camera-path 1\n0 0 0 5 0 0 0 0 1 0 40 7\n",                        // 12 numbers
      "treecut-camera-path 1\n0 0 0 5 0 0 0 0 1 0 4x0\n",                         // garbage token
      "treecut-camera-path 1\n0 0 0 nan 0 0 0 0 1 0 40\n",                        // not finite
      "treecut-camera-path 1\n0 0 0 1e999 0 0 0 0 1 0 40\n",                      // overflow
      "treecut-camera-path 1\n-1 0 0 5 0 0 0 0 1 0 40\n",                         // negative time
      "treecut-camera-path 1\n1 0 0 5 0 0 0 0 1 0 40\n0 0 0 5 0 0 0 0 1 0 40\n",  // backwards
      "treecut-camera-path 1\n0 0 0 0 0 0 0 0 1 0 40\n",                          // eye == target
      "treecut-camera-path 1\n0 0 0 5 0 0 0 0 0 0 40\n",                          // zero up
      "treecut-camera-path 1\n0 0 0 5 0 0 0 0 1 0 180\n",  // fov out of range
  };
  for (const char* text : bad) {
    EXPECT_THROW(parse_camera_path(text, "bad"), InputError) << text;
  }
  // Every truncation of a valid file either parses or throws InputError.
  const std::string good = kPath;
  for (std::size_t n = 0; n <= good.size(); ++n) {
    try {
      (void)parse_camera_path(good.substr(0, n), "cut");
    } catch (const InputError&) {
    }
  }
}

// Issue 43, item 12: the fit is the box's, not its bounding sphere's: every
// corner is in view, and one touches the 5 % margin of the frame (or the
// eye is 1.2 radii out), so a flat model fills the frame, not its middle
// third; the clip planes bracket every corner.
TEST(Camera, FitSeesTheWholeBoxAndFillsTheFrame) {
  const float aspect = 16.0f / 9.0f;
  for (const auto& [lo, hi] : {std::pair{glm::vec3(-2, 0, 1), glm::vec3(4, 3, 2)},
                               std::pair{glm::vec3(0, 0, 0), glm::vec3(100, 80, 2)}}) {
    for (glm::vec3 up : {glm::vec3(0, 1, 0), glm::vec3(0, 0, 1)}) {
      const Camera c = default_camera(lo, hi, aspect, up);
      const glm::mat4 vp = c.projection_matrix(aspect) * c.view_matrix();
      float reach = 0.0f;  // the farthest corner from the centre of the frame, in NDC
      for (int k = 0; k < 8; ++k) {
        const glm::vec3 corner((k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z);
        const glm::vec4 p = vp * glm::vec4(corner, 1.0f);
        ASSERT_GT(p.w, 0.0f);
        const glm::vec3 ndc = glm::vec3(p) / p.w;
        EXPECT_LE(std::fabs(ndc.x), 1.0f);
        EXPECT_LE(std::fabs(ndc.y), 1.0f);
        EXPECT_GE(ndc.z, -1.0f - 1e-5f) << "in front of the near plane";
        EXPECT_LE(ndc.z, 1.0f + 1e-5f) << "before the far plane";
        reach = std::max({reach, std::fabs(ndc.x), std::fabs(ndc.y)});
      }
      const float r = 0.5f * glm::length(hi - lo);
      const bool out = glm::length(c.eye - 0.5f * (lo + hi)) > 1.2f * r * 1.001f;
      if (!out) {
        EXPECT_GT(reach, 0.9f) << "a corner at the margin";
      }
      EXPECT_GT(glm::dot(c.eye - 0.5f * (lo + hi), up), 0.0f) << "seen from above";
    }
  }
  // The flat one fills more than two thirds of the frame's width.
  const Camera flat = default_camera({0, 0, 0}, {100, 80, 2}, aspect, {0, 0, 1});
  const glm::mat4 vp = flat.projection_matrix(aspect) * flat.view_matrix();
  float x_lo = 1.0f, x_hi = -1.0f;
  for (int k = 0; k < 8; ++k) {
    const glm::vec4 p = vp * glm::vec4((k & 1) ? 100.0f : 0.0f, (k & 2) ? 80.0f : 0.0f,
                                       (k & 4) ? 2.0f : 0.0f, 1.0f);
    x_lo = std::min(x_lo, p.x / p.w), x_hi = std::max(x_hi, p.x / p.w);
  }
  EXPECT_GT(x_hi - x_lo, 2.0f * 2.0f / 3.0f);
}

TEST(Camera, OrbitDirectionIsUnitAndTurnsAboutUp) {
  const glm::vec3 up(0, 0, 1);
  for (float az : {0.0f, 1.0f, 2.5f, 4.0f}) {
    const glm::vec3 d = orbit_direction(up, az, 0.3f);
    EXPECT_NEAR(glm::length(d), 1.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(d, up), std::sin(0.3f), 1e-5f);
  }
}

Image flat(int w, int h, std::uint8_t v) {
  return Image{w, h, std::vector<std::uint8_t>(std::size_t(w) * std::size_t(h) * 4, v)};
}

TEST(ImageMetrics, PsnrOfKnownError) {
  const Image a = flat(4, 4, 100);
  Image b = a;
  EXPECT_EQ(psnr(a, b), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < b.rgba.size(); i += 4) b.rgba[i] = 110;  // R off by 10
  // MSE = 100 / 3 over RGB.
  EXPECT_NEAR(psnr(a, b), 10.0 * std::log10(255.0 * 255.0 / (100.0 / 3.0)), 1e-9);
  // Alpha does not count.
  Image c = a;
  c.rgba[3] = 0;
  EXPECT_EQ(psnr(a, c), std::numeric_limits<double>::infinity());
  EXPECT_THROW((void)psnr(a, flat(4, 5, 100)), std::invalid_argument);
}

TEST(ImageMetrics, ChangedFractionCountsPixelsOverTheThreshold) {
  const Image a = flat(10, 10, 50);
  Image b = a;
  b.rgba[0] = 50 + 9;    // pixel 0 changes by 9 (over 8)
  b.rgba[5] = 50 + 8;    // pixel 1 changes by 8 (not over)
  b.rgba[10] = 50 - 20;  // pixel 2 changes
  EXPECT_DOUBLE_EQ(changed_fraction(a, b), 2.0 / 100.0);
  EXPECT_DOUBLE_EQ(changed_fraction(a, a), 0.0);
}

TEST(ImageMetrics, CoverageFindsBoxAndCentroid) {
  Image img = flat(8, 6, 0);
  const std::uint8_t bg[3] = {0, 0, 0};
  for (int y = 2; y <= 3; ++y) {
    for (int x = 4; x <= 6; ++x) img.rgba[(std::size_t(y) * 8 + std::size_t(x)) * 4 + 1] = 200;
  }
  const Coverage c = coverage(img, bg);
  EXPECT_EQ(c.pixels, 6u);
  EXPECT_EQ(c.min_x, 4);
  EXPECT_EQ(c.max_x, 6);
  EXPECT_EQ(c.min_y, 2);
  EXPECT_EQ(c.max_y, 3);
  EXPECT_DOUBLE_EQ(c.centroid_x, 5.0);
  EXPECT_DOUBLE_EQ(c.centroid_y, 2.5);
}

TEST(ImageMetrics, WritesAPngAndRejectsMalformedImages) {
  const auto dir = test::scratch_dir("image_png");
  write_png(dir / "a.png", flat(3, 2, 128));
  EXPECT_GT(std::filesystem::file_size(dir / "a.png"), 8u);
  Image bad = flat(3, 2, 0);
  bad.rgba.pop_back();
  EXPECT_THROW(write_png(dir / "b.png", bad), std::runtime_error);
}

}  // namespace
}  // namespace treecut::splat
