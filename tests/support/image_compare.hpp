// Image comparisons of the GL tests that must hold on any driver: what a
// driver's float rounding may change is a splat edge moved by a pixel or a
// blend weight rounded another way, not a colour that is nowhere near.
#pragma once

#include <stb/stb_image.h>

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <filesystem>

#include "treecut/splat/image.hpp"

namespace treecut::test {

/// Pixels of `a` whose colour (within `tolerance` per channel) is at no pixel
/// of `b` within one pixel of theirs (issue 28: NVIDIA and llvmpipe round
/// positions differently; an exact count was 1.3 % on llvmpipe, 3 % on an H200).
inline std::size_t unmatched_pixels(const splat::Image& a, const splat::Image& b,
                                    int tolerance = 8) {
  std::size_t d = 0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      const std::size_t i = (std::size_t(y) * a.width + x) * 4;
      bool found = false;
      for (int dy = -1; dy <= 1 && !found; ++dy) {
        for (int dx = -1; dx <= 1 && !found; ++dx) {
          const int u = x + dx, v = y + dy;
          if (u < 0 || v < 0 || u >= b.width || v >= b.height) continue;
          const std::size_t j = (std::size_t(v) * b.width + u) * 4;
          found = std::abs(int(a.rgba[i]) - int(b.rgba[j])) <= tolerance &&
                  std::abs(int(a.rgba[i + 1]) - int(b.rgba[j + 1])) <= tolerance &&
                  std::abs(int(a.rgba[i + 2]) - int(b.rgba[j + 2])) <= tolerance;
        }
      }
      d += found ? 0 : 1;
    }
  }
  return d;
}

/// unmatched_pixels both ways: the larger.
inline std::size_t unmatched_either_way(const splat::Image& a, const splat::Image& b) {
  return std::max(unmatched_pixels(a, b), unmatched_pixels(b, a));
}

/// A PNG's pixels, RGBA (empty when it cannot be read). The test that calls
/// it defines STB_IMAGE_IMPLEMENTATION in one file.
inline splat::Image load_png(const std::filesystem::path& png) {
  splat::Image im;
  int channels = 0;
  unsigned char* data = stbi_load(png.c_str(), &im.width, &im.height, &channels, 4);
  if (data == nullptr) return {};
  im.rgba.assign(data, data + std::size_t(im.width) * std::size_t(im.height) * 4);
  stbi_image_free(data);
  return im;
}

}  // namespace treecut::test
