// Packing points into blocks and back (point_blocks.hpp): a byte stream of
// the columns, compressed with zstd at its fastest level (a survey's
// classes, returns and colours shrink several times; the block costs far
// less than its reading from the disk).
#include "point_blocks.hpp"

#include <zstd.h>

#include <cstring>
#include <stdexcept>
#include <string>

namespace treecut::detail {

namespace {

constexpr std::uint32_t kNormals = 1, kRadii = 2, kCurvature = 4, kColors = 8, kColors16 = 16;
enum Form : std::uint8_t { kConstant, kFloats, kDoubles, kIntegers };

class Writer {
 public:
  template <class T>
  void put(const T& v) {
    const auto* p = reinterpret_cast<const unsigned char*>(&v);
    bytes.insert(bytes.end(), p, p + sizeof v);
  }
  template <class T>
  void gather(const std::vector<T>& column, std::span<const std::uint32_t> indices) {
    const std::size_t at = bytes.size();
    bytes.resize(at + indices.size() * sizeof(T));
    auto* out = reinterpret_cast<T*>(bytes.data() + at);  // byte vector: memcpy below
    for (std::size_t k = 0; k < indices.size(); ++k)
      std::memcpy(reinterpret_cast<unsigned char*>(out) + k * sizeof(T), &column[indices[k]],
                  sizeof(T));
  }
  std::vector<unsigned char> bytes;
};

class Reader {
 public:
  explicit Reader(std::span<const unsigned char> b) : b_(b) {}
  template <class T>
  T get() {
    T v;
    take(&v, sizeof v);
    return v;
  }
  template <class T>
  void column(std::vector<T>& v, std::size_t n) {
    v.resize(n);
    take(v.data(), n * sizeof(T));
  }
  std::string text(std::size_t n) {
    std::string s(n, '\0');
    take(s.data(), n);
    return s;
  }
  [[nodiscard]] bool done() const { return at_ == b_.size(); }

 private:
  void take(void* to, std::size_t n) {
    if (n > b_.size() - at_) throw std::runtime_error("a point block is cut short");
    std::memcpy(to, b_.data() + at_, n);
    at_ += n;
  }
  std::span<const unsigned char> b_;
  std::size_t at_ = 0;
};

}  // namespace

std::vector<unsigned char> pack_points(const PointSet& ps, std::span<const std::uint32_t> indices) {
  const std::size_t n = ps.size();
  Writer w;
  w.put(std::uint64_t{indices.size()});
  const std::uint32_t has =
      (ps.normals.size() == n ? kNormals : 0u) | (ps.radii.size() == n ? kRadii : 0u) |
      (ps.curvature.size() == n ? kCurvature : 0u) | (ps.colors.size() == n ? kColors : 0u) |
      (ps.colors16.size() == n ? kColors16 : 0u);
  w.put(has);
  w.put(static_cast<std::uint32_t>(ps.attributes.size()));
  w.gather(ps.positions, indices);
  if (has & kNormals) w.gather(ps.normals, indices);
  if (has & kRadii) w.gather(ps.radii, indices);
  if (has & kCurvature) w.gather(ps.curvature, indices);
  if (has & kColors) w.gather(ps.colors, indices);
  if (has & kColors16) w.gather(ps.colors16, indices);
  for (const PointAttribute& a : ps.attributes) {
    w.put(static_cast<std::uint32_t>(a.name.size()));
    w.bytes.insert(w.bytes.end(), a.name.begin(), a.name.end());
    w.put(static_cast<std::uint8_t>(a.kind));
    w.put(static_cast<std::uint8_t>(a.type));
    w.put(a.scale), w.put(a.base);
    w.put(static_cast<std::uint8_t>(a.no_data.has_value()));
    w.put(a.no_data.value_or(0.0));
    const Form form = !a.values.empty()     ? kFloats
                      : !a.wide.empty()     ? kDoubles
                      : !a.integers.empty() ? kIntegers
                                            : kConstant;
    w.put(static_cast<std::uint8_t>(form));
    w.put(a.offset), w.put(a.constant);
    if (form == kFloats) w.gather(a.values, indices);
    if (form == kDoubles) w.gather(a.wide, indices);
    if (form == kIntegers) w.gather(a.integers, indices);
  }
  std::vector<unsigned char> packed(ZSTD_compressBound(w.bytes.size()));
  const std::size_t size =
      ZSTD_compress(packed.data(), packed.size(), w.bytes.data(), w.bytes.size(), 1);
  if (ZSTD_isError(size)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(size));
  packed.resize(size);
  packed.shrink_to_fit();
  return packed;
}

PointSet unpack_points(std::span<const unsigned char> block) {
  const unsigned long long raw_size = ZSTD_getFrameContentSize(block.data(), block.size());
  if (raw_size == ZSTD_CONTENTSIZE_ERROR || raw_size == ZSTD_CONTENTSIZE_UNKNOWN)
    throw std::runtime_error("a point block is not a zstd frame");
  std::vector<unsigned char> raw(raw_size);
  const std::size_t got = ZSTD_decompress(raw.data(), raw.size(), block.data(), block.size());
  if (ZSTD_isError(got) || got != raw.size())
    throw std::runtime_error("a point block does not decompress");
  Reader r(raw);
  PointSet ps;
  const auto n = static_cast<std::size_t>(r.get<std::uint64_t>());
  if (n > raw.size() / sizeof(glm::vec3)) throw std::runtime_error("a point block is cut short");
  const auto has = r.get<std::uint32_t>();
  const auto attributes = r.get<std::uint32_t>();
  if (attributes > kMaxAttributes) throw std::runtime_error("a point block has too many fields");
  r.column(ps.positions, n);
  if (has & kNormals) r.column(ps.normals, n);
  if (has & kRadii) r.column(ps.radii, n);
  if (has & kCurvature) r.column(ps.curvature, n);
  if (has & kColors) r.column(ps.colors, n);
  if (has & kColors16) r.column(ps.colors16, n);
  for (std::uint32_t k = 0; k < attributes; ++k) {
    PointAttribute& a = ps.attributes.emplace_back();
    const auto name_size = r.get<std::uint32_t>();
    if (name_size > kMaxAttributeName) throw std::runtime_error("a point block's field name");
    a.name = r.text(name_size);
    a.kind = static_cast<AttributeKind>(r.get<std::uint8_t>());
    a.type = static_cast<ValueType>(r.get<std::uint8_t>());
    a.scale = r.get<double>(), a.base = r.get<double>();
    const bool no_data = r.get<std::uint8_t>() != 0;
    const double no_data_value = r.get<double>();
    if (no_data) a.no_data = no_data_value;
    const auto form = static_cast<Form>(r.get<std::uint8_t>());
    a.offset = r.get<double>(), a.constant = r.get<double>();
    if (form == kFloats) r.column(a.values, n);
    if (form == kDoubles) r.column(a.wide, n);
    if (form == kIntegers) r.column(a.integers, n);
  }
  if (!r.done()) throw std::runtime_error("a point block has bytes past its columns");
  return ps;
}

void keep_first(PointSet& ps, std::size_t n) {
  const auto cut = [n](auto& v) {
    if (v.size() > n) v.resize(n);
  };
  cut(ps.positions), cut(ps.exact_positions), cut(ps.normals), cut(ps.radii);
  cut(ps.colors), cut(ps.colors16), cut(ps.curvature);
  for (PointAttribute& a : ps.attributes) cut(a.values), cut(a.wide), cut(a.integers);
}

}  // namespace treecut::detail
