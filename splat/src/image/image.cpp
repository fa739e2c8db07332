#include "treecut/splat/image.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>

#include "treecut/file_io.hpp"

// The implementation is in libstb (libstb-dev); only the declarations here.
#include <stb_image_write.h>

namespace treecut::splat {

namespace {
void require_same_size(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height ||
      a.rgba.size() != static_cast<std::size_t>(a.width) * static_cast<std::size_t>(a.height) * 4 ||
      b.rgba.size() != a.rgba.size()) {
    throw std::invalid_argument("image metrics need two well-formed images of the same size");
  }
}
}  // namespace

namespace {
struct PngSink {
  std::string bytes;
  bool failed = false;
};

// Called from stb's C code: no exception may cross it, so a failed
// allocation is recorded and reported after stb returns.
void append_png(void* context, void* data, int size) {
  auto* sink = static_cast<PngSink*>(context);
  if (sink->failed || size <= 0) return;
  try {
    sink->bytes.append(static_cast<const char*>(data), static_cast<std::size_t>(size));
  } catch (const std::bad_alloc&) {
    sink->failed = true;
  }
}
}  // namespace

std::string encode_png(const Image& image) {
  if (image.empty() || image.rgba.size() != static_cast<std::size_t>(image.width) *
                                                static_cast<std::size_t>(image.height) * 4) {
    throw std::invalid_argument("cannot encode a malformed image as PNG");
  }
  PngSink sink;
  if (stbi_write_png_to_func(append_png, &sink, image.width, image.height, 4, image.rgba.data(),
                             image.width * 4) == 0 ||
      sink.failed) {
    throw std::runtime_error("PNG encoding failed (out of memory)");
  }
  return std::move(sink.bytes);
}

void write_png(const std::filesystem::path& path, const Image& image) {
  std::string bytes;
  try {
    bytes = encode_png(image);
  } catch (const std::exception& e) {
    throw std::runtime_error(quoted_name(path) + ": " + e.what());
  }
  // Encoded in memory first, then one checked atomic write: a full disk
  // leaves no truncated PNG that looks like a frame.
  write_file_atomically(path, bytes);
}

double psnr(const Image& a, const Image& b) {
  require_same_size(a, b);
  double sum = 0.0;
  const std::size_t pixels = a.rgba.size() / 4;
  for (std::size_t i = 0; i < pixels; ++i) {
    for (std::size_t c = 0; c < 3; ++c) {
      const double d = double(a.rgba[i * 4 + c]) - double(b.rgba[i * 4 + c]);
      sum += d * d;
    }
  }
  if (sum == 0.0) return std::numeric_limits<double>::infinity();
  const double mse = sum / (double(pixels) * 3.0);
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

double changed_fraction(const Image& a, const Image& b, int threshold) {
  require_same_size(a, b);
  const std::size_t pixels = a.rgba.size() / 4;
  if (pixels == 0) return 0.0;
  std::size_t changed = 0;
  for (std::size_t i = 0; i < pixels; ++i) {
    for (std::size_t c = 0; c < 3; ++c) {
      if (std::abs(int(a.rgba[i * 4 + c]) - int(b.rgba[i * 4 + c])) > threshold) {
        ++changed;
        break;
      }
    }
  }
  return double(changed) / double(pixels);
}

Coverage coverage(const Image& image, const std::uint8_t background[3], int threshold) {
  Coverage cov;
  cov.min_x = image.width;
  cov.min_y = image.height;
  double sx = 0.0, sy = 0.0, luma = 0.0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const std::uint8_t* p =
          &image.rgba[(static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) +
                       static_cast<std::size_t>(x)) *
                      4];
      bool differs = false;
      for (int c = 0; c < 3; ++c) differs |= std::abs(int(p[c]) - int(background[c])) > threshold;
      if (!differs) continue;
      ++cov.pixels;
      cov.min_x = std::min(cov.min_x, x);
      cov.min_y = std::min(cov.min_y, y);
      cov.max_x = std::max(cov.max_x, x);
      cov.max_y = std::max(cov.max_y, y);
      sx += x;
      sy += y;
      luma += 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    }
  }
  if (cov.pixels > 0) {
    cov.centroid_x = sx / double(cov.pixels);
    cov.centroid_y = sy / double(cov.pixels);
    cov.mean_luma = luma / double(cov.pixels);
  } else {
    cov.min_x = cov.min_y = 0;
  }
  return cov;
}

}  // namespace treecut::splat
