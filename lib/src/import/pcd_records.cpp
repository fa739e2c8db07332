// The records of a PCD body as points (pcd_records.hpp).
#include "pcd_records.hpp"

#include <lzf.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <glm/gtc/quaternion.hpp>
#include <limits>

#include "little_endian.hpp"

namespace treecut::pcd {

namespace {

double element(const unsigned char* p, const Field& f) {
  switch (f.type) {
    case 'F':
      return f.size == 4 ? double(detail::get_le<float>(p)) : detail::get_le<double>(p);
    case 'I':
      switch (f.size) {
        case 1:
          return static_cast<std::int8_t>(*p);
        case 2:
          return detail::get_le<std::int16_t>(p);
        case 4:
          return detail::get_le<std::int32_t>(p);
        default:
          return static_cast<double>(detail::get_le<std::int64_t>(p));
      }
    default:
      switch (f.size) {
        case 1:
          return *p;
        case 2:
          return detail::get_le<std::uint16_t>(p);
        case 4:
          return detail::get_le<std::uint32_t>(p);
        default:
          return static_cast<double>(detail::get_le<std::uint64_t>(p));
      }
  }
}

std::string lower(std::string_view name) {
  std::string s(name);
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

// Field names are matched without regard to case (PDAL and others write
// X Y Z, Red Green Blue); attributes keep the file's spelling.
Roles roles_of(const Header& h) {
  Roles r;
  static const std::vector<std::vector<std::string_view>> kNames = {{"x"},
                                                                    {"y"},
                                                                    {"z"},
                                                                    {"normal_x", "nx"},
                                                                    {"normal_y", "ny"},
                                                                    {"normal_z", "nz"},
                                                                    {"red", "r"},
                                                                    {"green", "g"},
                                                                    {"blue", "b"}};
  for (int i = 0; i < static_cast<int>(h.fields.size()); ++i) {
    const Field& f = h.fields[static_cast<std::size_t>(i)];
    const std::string name = lower(f.name);
    int role = -1;
    for (std::size_t k = 0; k < kNames.size() && role < 0 && f.count == 1; ++k) {
      if (std::find(kNames[k].begin(), kNames[k].end(), name) != kNames[k].end()) role = int(k);
    }
    int* slot = role < 0   ? nullptr
                : role < 3 ? &r.xyz[role]
                : role < 6 ? &r.normal[role - 3]
                           : &r.channel[role - 6];
    bool placed = false;
    if (slot != nullptr && *slot < 0) *slot = i, placed = true;
    if ((name == "rgb" || name == "rgba") && f.count == 1 && f.size == 4 && r.rgb < 0) {
      r.rgb = i, placed = true;
    }
    if (placed || f.name == "_") continue;
    if (f.count == 1 && r.attributes.size() < kMaxAttributes) {
      r.attributes.push_back(i);
    } else {
      r.not_kept.push_back(shown(f.name) +
                           (f.count > 1 ? " (" + std::to_string(f.count) + " values)" : ""));
    }
  }
  if (r.xyz[0] < 0 || r.xyz[1] < 0 || r.xyz[2] < 0) throw PcdError("no x, y and z fields");
  // A normal or a colour counts only whole; a packed colour wins over channels.
  for (int* triple : {r.normal, r.channel}) {
    const bool whole = triple[0] >= 0 && triple[1] >= 0 && triple[2] >= 0;
    if (whole && !(triple == r.channel && r.rgb >= 0)) continue;
    for (int k = 0; k < 3; ++k) {
      if (triple[k] >= 0) r.attributes.push_back(triple[k]);
      triple[k] = -1;
    }
  }
  std::sort(r.attributes.begin(), r.attributes.end());
  return r;
}

ValueType value_type(const Field& f) {
  if (f.type == 'F') return f.size == 4 ? ValueType::f32 : ValueType::f64;
  const bool s = f.type == 'I';
  switch (f.size) {
    case 1:
      return s ? ValueType::i8 : ValueType::u8;
    case 2:
      return s ? ValueType::i16 : ValueType::u16;
    case 4:
      return s ? ValueType::i32 : ValueType::u32;
    default:
      return s ? ValueType::i64 : ValueType::u64;
  }
}

void read_packed(const unsigned char* body, const Header& h, Builder& b) {
  for (std::uint64_t i = 0; i < h.points; ++i) {
    const unsigned char* rec = body + i * h.record;
    b.add(
        [&](int f) {
          const Field& x = h.fields[static_cast<std::size_t>(f)];
          return element(rec + x.offset, x);
        },
        [&](int f) {
          return detail::get_le<std::uint32_t>(rec + h.fields[static_cast<std::size_t>(f)].offset);
        },
        [&](int f) -> std::optional<std::uint64_t> {
          return detail::get_le<std::uint64_t>(rec + h.fields[static_cast<std::size_t>(f)].offset);
        });
  }
}

// binary_compressed: the fields one after the other, each for every point.
void read_columns(const unsigned char* body, const Header& h, Builder& b) {
  std::vector<std::uint64_t> start(h.fields.size());
  std::uint64_t at = 0;
  for (std::size_t f = 0; f < h.fields.size(); ++f) {
    start[f] = at;
    at += std::uint64_t{h.fields[f].size} * h.fields[f].count * h.points;
  }
  for (std::uint64_t i = 0; i < h.points; ++i) {
    auto where = [&](int f) {
      const Field& x = h.fields[static_cast<std::size_t>(f)];
      return body + start[static_cast<std::size_t>(f)] + i * x.size * x.count;
    };
    b.add([&](int f) { return element(where(f), h.fields[static_cast<std::size_t>(f)]); },
          [&](int f) { return detail::get_le<std::uint32_t>(where(f)); },
          [&](int f) -> std::optional<std::uint64_t> {
            return detail::get_le<std::uint64_t>(where(f));
          });
  }
}

void read_ascii(std::string_view file, const Header& h, Builder& b) {
  std::size_t at = h.body, line = h.body_line - 1;
  std::uint64_t per_line = 0;
  for (const Field& f : h.fields) per_line += f.count;
  std::vector<std::size_t> first(h.fields.size());  // token of each field
  std::size_t k = 0;
  for (std::size_t f = 0; f < h.fields.size(); ++f) first[f] = k, k += h.fields[f].count;
  std::vector<double> values;
  std::uint64_t read = 0;
  while (read < h.points) {
    if (at >= file.size()) {
      throw PcdError(std::to_string(h.points) + " points declared, the file has " +
                     std::to_string(read));
    }
    const std::size_t end = std::min(file.find('\n', at), file.size());
    const std::string_view text = trim(file.substr(at, end - at));
    at = end + 1;
    ++line;
    if (text.empty()) continue;
    const std::vector<std::string_view> t = tokens_of(text);
    if (t.size() != per_line) {
      throw PcdError(std::to_string(line) + ": " + std::to_string(t.size()) +
                     " values, the fields have " + std::to_string(per_line));
    }
    values.resize(t.size());
    for (std::size_t i = 0; i < t.size(); ++i) {
      std::string_view s = t[i];
      if (s == "nan" || s == "NaN" || s == "-nan") {
        values[i] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      if (!s.empty() && s.front() == '+') s.remove_prefix(1);
      const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), values[i]);
      if (ec != std::errc() || p != s.data() + s.size()) {
        throw PcdError(std::to_string(line) + ": '" + shown(t[i]) + "' is not a number");
      }
    }
    b.add([&](int f) { return values[first[static_cast<std::size_t>(f)]]; },
          [&](int f) {
            // A packed colour is written as the float with its bits (or an integer).
            const Field& x = h.fields[static_cast<std::size_t>(f)];
            const double v = values[first[static_cast<std::size_t>(f)]];
            if (x.type == 'F') {
              const float fv = static_cast<float>(v);
              std::uint32_t bits;
              std::memcpy(&bits, &fv, 4);
              return bits;
            }
            return static_cast<std::uint32_t>(std::clamp(v, 0.0, 4294967295.0));
          },
          [&](int f) -> std::optional<std::uint64_t> {
            // An 8-byte integer from its digits (a double rounds past 2^53);
            // anything else (nan) goes as a value.
            const Field& x = h.fields[static_cast<std::size_t>(f)];
            std::string_view token = t[first[static_cast<std::size_t>(f)]];
            if (!token.empty() && token.front() == '+') token.remove_prefix(1);
            const char* last = token.data() + token.size();
            std::uint64_t u = 0;
            std::int64_t i = 0;
            if (x.type == 'U') {
              const auto [p, ec] = std::from_chars(token.data(), last, u);
              if (ec == std::errc() && p == last) return u;
            } else {
              const auto [p, ec] = std::from_chars(token.data(), last, i);
              if (ec == std::errc() && p == last) return static_cast<std::uint64_t>(i);
            }
            return std::nullopt;
          });
    ++read;
  }
}

// binary_compressed: the LZF block's sizes checked against the file, the
// header and LZF's bound before anything is allocated, then unpacked.
std::vector<unsigned char> unpack(const unsigned char* body, std::uint64_t left, const Header& h,
                                  std::uint64_t need) {
  if (left < 8) throw PcdError("the compressed data's sizes are cut off");
  const std::uint32_t packed = detail::get_le<std::uint32_t>(body);
  const std::uint32_t unpacked = detail::get_le<std::uint32_t>(body + 4);
  if (packed > left - 8) {
    throw PcdError("the compressed data (" + std::to_string(packed) +
                   " bytes) runs past the end of the file");
  }
  if (unpacked != need) {
    throw PcdError("the compressed data unpacks to " + std::to_string(unpacked) + " bytes, " +
                   std::to_string(h.points) + " points of " + std::to_string(h.record) +
                   " bytes need " + std::to_string(need));
  }
  // LZF turns 3 bytes into at most 264: a larger claim is not LZF.
  if (need > std::uint64_t{packed} * 88 + 1024) {
    throw PcdError("the compressed data's " + std::to_string(packed) + " bytes cannot unpack to " +
                   std::to_string(need));
  }
  std::vector<unsigned char> columns(static_cast<std::size_t>(need));
  const unsigned got = need == 0 ? 0 : lzf_decompress(body + 8, packed, columns.data(), unpacked);
  if (got != unpacked) throw PcdError("the compressed data is damaged (LZF)");
  return columns;
}

// The sensor's pose (VIEWPOINT) of an organized cloud, or of any cloud
// whose pose is not the identity: the first view opens from it.
void set_viewpoint(const Header& h, PointSet& points) {
  const double* v = h.viewpoint;
  const glm::dquat q(v[3], v[4], v[5], v[6]);
  const bool identity = v[0] == 0 && v[1] == 0 && v[2] == 0 && q == glm::dquat(1, 0, 0, 0);
  if (identity && h.height <= 1) return;
  const double norm = glm::length(q);
  if (!(norm > 1e-9)) return;  // no rotation at all: not a pose
  points.frame.viewpoint = Viewpoint{glm::dvec3(v[0], v[1], v[2]), q / norm};
}

}  // namespace treecut::pcd
