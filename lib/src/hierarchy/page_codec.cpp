// One page of a hierarchy cache as bytes (page_codec.hpp): the quantization
// of its values and the byte planes they are stored in.
#include "page_codec.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <type_traits>

namespace treecut::cache_pages {

namespace {

// Byte planes: byte b of every value, then byte b + 1, ... (zstd finds the
// runs in the high bytes that interleaved values hide).
class PlaneWriter {
 public:
  explicit PlaneWriter(std::vector<unsigned char>& out) : out_(out) {}
  template <class T, class Get>
  void put(std::size_t count, Get&& get) {
    const std::size_t at = out_.size();
    out_.resize(at + count * sizeof(T));
    unsigned char* p = out_.data() + at;
    for (std::size_t i = 0; i < count; ++i) {
      const T v = get(i);
      unsigned char b[sizeof(T)];
      std::memcpy(b, &v, sizeof(T));
      for (std::size_t k = 0; k < sizeof(T); ++k) p[k * count + i] = b[k];
    }
  }

 private:
  std::vector<unsigned char>& out_;
};

class PlaneReader {
 public:
  PlaneReader(const unsigned char* at) : at_(at) {}
  // The plane group of COUNT values of T; value(i) reads the i-th.
  template <class T>
  struct Planes {
    const unsigned char* p;
    std::size_t count;
    T operator[](std::size_t i) const {
      if constexpr (sizeof(T) == 1) {
        return static_cast<T>(p[i]);
      } else if constexpr (sizeof(T) == 2) {
        return static_cast<T>(static_cast<std::uint16_t>(p[i] | (p[count + i] << 8)));
      } else {
        unsigned char b[sizeof(T)];
        for (std::size_t k = 0; k < sizeof(T); ++k) b[k] = p[k * count + i];
        T v;
        std::memcpy(&v, b, sizeof(T));
        return v;
      }
    }
  };
  template <class T>
  Planes<T> take(std::size_t count) {
    Planes<T> planes{at_, count};
    at_ += count * sizeof(T);
    return planes;
  }

 private:
  const unsigned char* at_;
};

// Each node's parent inside the page (-1 for the page's root): in-page
// children follow their parents in local order, taken in turn.
std::vector<std::int32_t> local_parents(const std::vector<std::uint8_t>& cc) {
  std::vector<std::int32_t> parent(cc.size(), -1);
  std::size_t next = 1;
  for (std::size_t k = 0; k < cc.size(); ++k) {
    if (cc[k] & kExternal) continue;
    for (unsigned c = 0; c < (cc[k] & kCountBits) && next < cc.size(); ++c)
      parent[next++] = static_cast<std::int32_t>(k);
  }
  return parent;
}

// The parent prediction: a node is stored as its difference from its
// parent (zigzag, so small either way is small), which leaves the high byte
// planes nearly constant for zstd: children lie near their parent, face
// its way, and share its colour.
template <class T>
T zigzag(T v, T parent) {
  using S = std::make_signed_t<T>;
  using U = std::make_unsigned_t<T>;
  const auto d = static_cast<S>(static_cast<U>(static_cast<U>(v) - static_cast<U>(parent)));
  return static_cast<T>(
      static_cast<U>((static_cast<U>(d) << 1) ^ static_cast<U>(d >> (8 * sizeof(T) - 1))));
}

template <class T>
T unzigzag(T z, T parent) {
  using U = std::make_unsigned_t<T>;
  const auto u = static_cast<U>(z);
  const auto d = static_cast<U>((u >> 1) ^ static_cast<U>(-static_cast<U>(u & 1u)));
  return static_cast<T>(static_cast<U>(static_cast<U>(parent) + d));
}

// The exponent of the smallest power of two >= X (X > 0).
int ceil_log2(double x) {
  int e = 0;
  const double m = std::frexp(x, &e);  // x = m 2^e, m in [0.5, 1)
  return m == 0.5 ? e - 1 : e;
}

// The exponent of the largest power of two that divides D (> 0).
int lowest_bit(double d) {  // from the bits: frexp and ldexp are calls
  const auto bits = std::bit_cast<std::uint64_t>(d);
  const auto biased = static_cast<int>(bits >> 52);  // d > 0: no sign bit
  const std::uint64_t mantissa =
      (bits & ((std::uint64_t{1} << 52) - 1)) | (biased != 0 ? std::uint64_t{1} << 52 : 0);
  return (biased != 0 ? biased : 1) - 1075 + std::countr_zero(mantissa);
}

}  // namespace

// 2^(j / 512) for j < 512: the radius grid's mantissas (exact in double,
// rounded once to float; the same table encodes and decodes).
const std::array<float, 512>& radius_mantissas() {
  static const std::array<float, 512> table = [] {
    std::array<float, 512> t{};
    for (int j = 0; j < 512; ++j) t[static_cast<std::size_t>(j)] = float(std::exp2(j / 512.0));
    return t;
  }();
  return table;
}

// Radii lie on one absolute grid, index J: 2^(J / 512). A page stores
// J - 512 * radius_exp in 16 bits.
// The smallest index whose radius is at least NEED (> 0, finite).
std::int32_t radius_index(float need) {
  if (!(need > 0.0f) || !std::isfinite(need))
    throw std::runtime_error("a radius that is not a positive number");
  const auto bits = std::bit_cast<std::uint32_t>(need);
  const auto biased = static_cast<std::int32_t>(bits >> 23);
  if (biased == 0) {  // subnormal: from the logarithm, then exact
    auto j = static_cast<std::int32_t>(std::ceil(std::log2(double(need)) * 512.0));
    while (radius_at(j) < need) ++j;
    while (radius_at(j - 1) >= need) --j;
    return j;
  }
  // NEED = f 2^octave with f in [1, 2): the first mantissa not below f.
  const float f = std::bit_cast<float>((bits & 0x007fffffu) | 0x3f800000u);
  // The first mantissa of F's bucket (its top 9 mantissa bits), then at
  // most two steps on: a bucket of [1, 2) holds at most two of the grid's
  // mantissas (512 log2 f grows by at most 1.44 across one). A binary
  // search of the 512 took 3 % of a chunked build's samples.
  const std::array<float, 512>& m = radius_mantissas();
  static const std::array<std::uint16_t, 512> first = [&m] {
    std::array<std::uint16_t, 512> t{};
    for (std::uint32_t k = 0; k < 512; ++k)
      t[k] = static_cast<std::uint16_t>(
          std::lower_bound(m.begin(), m.end(), std::bit_cast<float>(0x3f800000u | (k << 14))) -
          m.begin());
    return t;
  }();
  std::uint32_t at = first[(bits & 0x007fffffu) >> 14];
  while (at < 512 && m[at] < f) ++at;
  return 512 * (biased - 127) + static_cast<std::int32_t>(at);  // 512: the next octave's first
}

// The coarsest grid on which every one of VALUES lies exactly, if 65536
// steps of it span them: how a page's (quantized) values are stored, so
// that values already on a grid keep it (the encoding is idempotent).
std::optional<AxisGrid> exact_grid(const std::vector<float>& values) {
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  if (*lo == *hi) return AxisGrid::of(*lo, -126);
  // The grid's exponent only falls as values come: once the span needs
  // more than 65536 steps of it, no grid holds them (raw floats fail fast).
  const double span = double(*hi) - double(*lo);
  int exp = 1024;
  for (const float v : values) {
    const double d = double(v) - double(*lo);
    if (d <= 0.0) continue;
    exp = std::min(exp, lowest_bit(d));
    if (span > std::ldexp(65535.0, exp)) return std::nullopt;
  }
  return AxisGrid::of(*lo, exp);
}

// Where values on no such grid go first: a power-of-two step fine enough
// that 65534 steps span [lo, hi], coarse enough (two ulps of the largest
// magnitude) that every grid value is a float; the values rounded to it.
void round_to_grid(std::vector<float>& values) {
  const auto [lo_it, hi_it] = std::minmax_element(values.begin(), values.end());
  const float lo = *lo_it, hi = *hi_it;
  const double extent = double(hi) - double(lo);
  int exp = extent > 0.0 ? ceil_log2(extent / 65534.0) : -126;
  int m_exp = 0;
  (void)std::frexp(std::max(std::fabs(lo), std::fabs(hi)), &m_exp);
  exp = std::max({exp, m_exp - 23, -126});
  const double step = std::ldexp(1.0, exp);
  const double corner = std::floor(double(lo) / step) * step;
  for (float& v : values)
    v = float(corner + std::min(std::round((double(v) - corner) / step), 65535.0) * step);
}

std::uint16_t encode_axis(float v, const AxisGrid& g) {  // V on the grid: exact
  return static_cast<std::uint16_t>((double(v) - double(g.lo)) * g.inverse);
}

std::uint8_t encode_splat(float splat, float radius) {
  return static_cast<std::uint8_t>(std::clamp(std::lround(splat / radius * 255.0f), 1L, 255L));
}

std::uint16_t encode_priority(float p) {
  return static_cast<std::uint16_t>(std::lround(std::clamp(p, 0.0f, 1.0f) * 4095.0f));
}

// The z a unit normal with X and Y has, in snorm16, without its sign: the
// planes store z as its difference from this (0 or +-1 on most nodes, a
// byte zstd all but drops), so a normal costs about 4 bytes, exactly.
std::int16_t unit_z(std::int16_t x, std::int16_t y) {  // any rule will do: both sides use it
  const double fx = x / 32767.0, fy = y / 32767.0;
  return static_cast<std::int16_t>(std::sqrt(std::max(0.0, 1.0 - fx * fx - fy * fy)) * 32767.0 +
                                   0.5);
}

// The head, then the planes (raw_size()'s order), each value as its
// difference from its parent's.
std::vector<unsigned char> write_planes(const PageCodes& c) {
  const PageHead& head = c.head;
  const std::size_t n = head.node_count;
  const std::vector<std::int32_t> parent = local_parents(c.cc);
  std::vector<std::size_t> interior, leaves;
  for (std::size_t k = 0; k < n; ++k) ((c.cc[k] & kCountBits) ? interior : leaves).push_back(k);
  std::vector<unsigned char> out(sizeof head);
  std::memcpy(out.data(), &head, sizeof head);
  out.reserve(raw_size(head));
  PlaneWriter w(out);
  auto predicted = [&](const auto& v, std::size_t k) {
    using T = std::decay_t<decltype(v[0])>;
    return zigzag<T>(v[k], parent[k] < 0 ? T{0} : v[static_cast<std::size_t>(parent[k])]);
  };
  w.put<std::uint8_t>(n, [&](std::size_t k) { return c.cc[k]; });
  for (const auto& axis : c.q)
    w.put<std::uint16_t>(n, [&](std::size_t k) { return predicted(axis, k); });
  w.put<std::uint16_t>(n, [&](std::size_t k) { return predicted(c.radius, k); });
  for (int m = 0; m < 2; ++m)
    w.put<std::int16_t>(n, [&](std::size_t k) { return predicted(c.normal[m], k); });
  w.put<std::int16_t>(n, [&](std::size_t k) {
    const std::int16_t z = unit_z(c.normal[0][k], c.normal[1][k]);
    return static_cast<std::int16_t>(static_cast<std::uint16_t>(c.normal[2][k]) -
                                     static_cast<std::uint16_t>((c.cc[k] & kNegativeZ) ? -z : z));
  });
  w.put<std::int16_t>(interior.size(),
                      [&](std::size_t k) { return predicted(c.normal[3], interior[k]); });
  if (head.flags & kLeafCones)
    w.put<std::int16_t>(leaves.size(), [&](std::size_t k) { return c.normal[3][leaves[k]]; });
  for (int m = 0; m < 3; ++m)
    w.put<std::uint8_t>(n, [&](std::size_t k) { return predicted(c.color[m], k); });
  if (head.flags & kAlpha) w.put<std::uint8_t>(n, [&](std::size_t k) { return c.color[3][k]; });
  w.put<std::uint16_t>(n, [&](std::size_t k) { return predicted(c.priority, k); });
  w.put<std::uint8_t>(interior.size(), [&](std::size_t k) { return c.splat[interior[k]]; });
  for (const auto& v : c.values)  // float bits: xor with the parent's
    w.put<std::uint32_t>(n, [&](std::size_t k) {
      return parent[k] < 0 ? v[k] : v[k] ^ v[static_cast<std::size_t>(parent[k])];
    });
  return out;
}

// The codes of a page's planes (write_planes undone, parents first).
PageCodes read_planes(const PageHead& h, const unsigned char* planes) {
  PageCodes c(h);
  const std::size_t n = h.node_count;
  PlaneReader r(planes + sizeof(PageHead));
  const auto cc = r.take<std::uint8_t>(n);
  for (std::size_t k = 0; k < n; ++k) c.cc[k] = cc[k];
  const std::vector<std::int32_t> parent = local_parents(c.cc);
  auto undo = [&](auto& v, const auto& plane) {
    using T = std::decay_t<decltype(v[0])>;
    for (std::size_t k = 0; k < n; ++k)
      v[k] = unzigzag<T>(plane[k], parent[k] < 0 ? T{0} : v[static_cast<std::size_t>(parent[k])]);
  };
  for (auto& axis : c.q) undo(axis, r.take<std::uint16_t>(n));
  undo(c.radius, r.take<std::uint16_t>(n));
  for (int m = 0; m < 2; ++m) undo(c.normal[m], r.take<std::int16_t>(n));
  const auto dz = r.take<std::int16_t>(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::int16_t z = unit_z(c.normal[0][k], c.normal[1][k]);
    c.normal[2][k] =
        static_cast<std::int16_t>(static_cast<std::uint16_t>(dz[k]) +
                                  static_cast<std::uint16_t>((c.cc[k] & kNegativeZ) ? -z : z));
  }
  const auto inner_cone = r.take<std::int16_t>(h.interior_count);
  const auto leaf_cones = r.take<std::int16_t>(h.flags & kLeafCones ? n - h.interior_count : 0);
  for (int m = 0; m < 3; ++m) undo(c.color[m], r.take<std::uint8_t>(n));
  if (h.flags & kAlpha) {
    const auto alpha = r.take<std::uint8_t>(n);
    for (std::size_t k = 0; k < n; ++k) c.color[3][k] = alpha[k];
  }
  undo(c.priority, r.take<std::uint16_t>(n));
  const auto splat = r.take<std::uint8_t>(h.interior_count);
  std::size_t inner = 0, leaf = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (c.cc[k] & kCountBits) {
      // An interior node's parent is interior: its cone is decoded already.
      const std::int16_t p =
          parent[k] < 0 ? std::int16_t{0} : c.normal[3][static_cast<std::size_t>(parent[k])];
      c.normal[3][k] = unzigzag<std::int16_t>(inner_cone[inner], p);
      c.splat[k] = splat[inner++];
    } else {
      const glm::i16vec4 nc(c.normal[0][k], c.normal[1][k], c.normal[2][k], 0);
      c.normal[3][k] = h.flags & kLeafCones ? leaf_cones[leaf++] : leaf_cone(nc);
    }
  }
  for (auto& v : c.values) {
    const auto bits = r.take<std::uint32_t>(n);
    for (std::size_t k = 0; k < n; ++k)
      v[k] = parent[k] < 0 ? bits[k] : bits[k] ^ v[static_cast<std::size_t>(parent[k])];
  }
  return c;
}

}  // namespace treecut::cache_pages
