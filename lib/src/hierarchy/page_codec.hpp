// One page of a hierarchy cache, as bytes (cache_pages.hpp says what a page
// keeps and how exactly): its head, the values of its nodes as integers
// (PageCodes), the quantization that makes them, and the byte planes they
// are stored in, each value as its difference from its parent's. Shared by
// the encoder (cache_pages.cpp) and the decoder (cache_page_decode.cpp).
// Private to the library.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "treecut/hierarchy.hpp"

namespace treecut::cache_pages {

// The head of a page's raw bytes; the byte planes follow (raw_size()).
struct PageHead {
  float lo[3];               // the grid's corner, on the grid
  std::int32_t step_exp[3];  // the grid's step: 2^step_exp an axis
  std::int32_t radius_exp;   // radius code q: 2^(radius_exp + q / 512)
  std::uint32_t flags;       // kLeafCones, kAlpha
  std::uint32_t node_count;
  std::uint32_t interior_count;
  std::uint32_t value_streams;  // non-constant attributes
};
static_assert(sizeof(PageHead) == 44);

constexpr std::uint32_t kLeafCones = 1;  // leaves' cone cosines stored (not the rule below)
constexpr std::uint32_t kAlpha = 2;      // alphas stored (not all 255)
// A node's byte: its child count, whether its children are in other pages,
// whether its normal's z is negative (the planes hold x and y, and z as its
// difference from the unit vector's, +-sqrt(1 - x^2 - y^2)).
constexpr std::uint8_t kCountBits = 7, kExternal = 8, kNegativeZ = 16;

inline std::uint64_t raw_size(const PageHead& h) {
  const std::uint64_t n = h.node_count, ni = h.interior_count;
  std::uint64_t bytes = sizeof(PageHead) + n * (1 + 6 + 2 + 6 + 3 + 2) + ni * (2 + 1);
  if (h.flags & kLeafCones) bytes += (n - ni) * 2;
  if (h.flags & kAlpha) bytes += n;
  return bytes + std::uint64_t{h.value_streams} * n * 4;
}

// A leaf's cone without kLeafCones: the builder's, 1 for a normal, a full
// cone for none.
inline std::int16_t leaf_cone(glm::i16vec4 nc) {
  return nc.x == 0 && nc.y == 0 && nc.z == 0 ? std::int16_t{-32767} : std::int16_t{32767};
}

// ---- Quantization (each decode is exact and each encode of a decoded
// value gives its code back: the encoding is idempotent) ----------------------

/// 2^(j / 512) for j < 512 (exact in double, rounded once to float).
const std::array<float, 512>& radius_mantissas();

/// Radii lie on one absolute grid of index J: 2^(J / 512). A page stores
/// J - 512 * radius_exp in 16 bits. (The decoders are inline: a call per
/// value cost a tenth of a cache's opening.)
inline float radius_at(std::int32_t j) {
  const std::int32_t octave = j >= 0 ? j / 512 : -((511 - j) / 512);
  const float mantissa = radius_mantissas()[static_cast<std::size_t>(j - 512 * octave)];
  if (octave < -125 || octave > 126) return std::ldexp(mantissa, octave);
  // 2^octave from its exponent bits: ldexp is a call.
  return mantissa * std::bit_cast<float>(static_cast<std::uint32_t>(octave + 127) << 23);
}
inline float decode_radius(std::uint16_t q, int exp) {
  return radius_at(512 * exp + q);
}
/// The smallest index whose radius is at least NEED (> 0, finite; throws
/// otherwise).
std::int32_t radius_index(float need);

/// One axis of a page's grid: values lo + q 2^exp, q < 65536.
struct AxisGrid {
  float lo = 0.0f;
  int exp = -126;
  double step = 0.0, inverse = 0.0;  // 2^exp, 2^-exp: exact in double
  static AxisGrid of(float lo, int exp) {
    return {lo, exp, std::ldexp(1.0, exp), std::ldexp(1.0, -exp)};
  }
};
/// The coarsest grid on which every one of VALUES lies exactly, if 65536
/// steps of it span them: how a page's (quantized) values are stored, so
/// that values already on a grid keep it.
std::optional<AxisGrid> exact_grid(const std::vector<float>& values);
/// Where values on no such grid go first: a power-of-two step fine enough
/// that 65534 steps span them, coarse enough (two ulps of the largest
/// magnitude) that every grid value is a float; the values rounded to it.
void round_to_grid(std::vector<float>& values);
std::uint16_t encode_axis(float v, const AxisGrid& g);          // V on the grid
inline float decode_axis(std::uint16_t q, const AxisGrid& g) {  // exact: a float on the grid
  return float(double(g.lo) + double(q) * g.step);
}

std::uint8_t encode_splat(float splat, float radius);
inline float decode_splat(std::uint8_t k, float radius) {
  const float s = std::min(radius, radius * float(k) / 255.0f);
  return s > 0.0f ? s : radius;
}
std::uint16_t encode_priority(float p);
inline float decode_priority(std::uint16_t q) {
  return float(q) / 4095.0f;
}

// ---- A page's values and its planes ----------------------------------------

// One page's values as integers, in local order: what the planes hold
// before the parent prediction (write_planes) and after it is undone
// (read_planes). Interior-only values (cone, splat) are kept for every
// node and written for the interior ones.
struct PageCodes {
  PageHead head{};
  std::vector<std::uint8_t> cc;  // child count | kExternal
  std::array<std::vector<std::uint16_t>, 3> q;
  std::vector<std::uint16_t> radius, priority;
  std::array<std::vector<std::int16_t>, 4> normal;  // x y z, cone
  std::array<std::vector<std::uint8_t>, 4> color;
  std::vector<std::uint8_t> splat;
  std::vector<std::vector<std::uint32_t>> values;  // float bits

  explicit PageCodes(const PageHead& h) : head(h) {
    const std::size_t n = h.node_count;
    cc.resize(n), radius.resize(n), priority.resize(n), splat.resize(n);
    for (auto& v : q) v.resize(n);
    for (auto& v : normal) v.resize(n);
    for (auto& v : color) v.assign(n, 255);
    values.assign(h.value_streams, std::vector<std::uint32_t>(n));
  }
};

/// The head, then the planes (raw_size()'s order), each value as its
/// difference from its parent's in the page.
std::vector<unsigned char> write_planes(const PageCodes& c);
/// The codes of the planes after HEAD (raw_size(HEAD) bytes in all, the
/// head included): write_planes undone, parents first.
PageCodes read_planes(const PageHead& head, const unsigned char* planes);

}  // namespace treecut::cache_pages
