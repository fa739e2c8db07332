// RGBA8 images: PNG output (stb_image_write) and the image metrics of the
// renderer's evaluation. No GL; any thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace treecut::splat {

/// Tightly packed RGBA8, top row first.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;

  [[nodiscard]] bool empty() const { return width <= 0 || height <= 0; }
};

/// The PNG file's bytes (encoded in memory). Throws std::invalid_argument for
/// a malformed image.
std::string encode_png(const Image& image);

/// Writes a PNG atomically (AtomicFile: temporary + rename, every write
/// checked): a failure leaves PATH as it was. Throws std::runtime_error
/// "PATH: REASON" on failure, a directory or FIFO at PATH included.
void write_png(const std::filesystem::path& path, const Image& image);

/// Peak signal-to-noise ratio in dB over the RGB channels of two images of the
/// same size (throws std::invalid_argument otherwise). Identical images give
/// +infinity.
double psnr(const Image& a, const Image& b);

/// Fraction of pixels in [0, 1] whose RGB differ by more than `threshold` (0..255)
/// in any channel: the temporal-stability measure between consecutive frames.
double changed_fraction(const Image& a, const Image& b, int threshold = 8);

/// Pixels whose RGB differ from `background` (sRGB bytes) by more than
/// `threshold` in any channel, with their bounding box and centroid. For tests
/// ("renders something, centered").
struct Coverage {
  std::size_t pixels = 0;
  int min_x = 0, min_y = 0, max_x = -1, max_y = -1;
  double centroid_x = 0.0, centroid_y = 0.0;  ///< pixels, image coordinates
  double mean_luma = 0.0;                     ///< of the covered pixels, 0..255
};
Coverage coverage(const Image& image, const std::uint8_t background[3], int threshold = 6);

}  // namespace treecut::splat
