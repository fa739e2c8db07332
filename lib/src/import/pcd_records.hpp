// A PCD body's records as points (pcd_read.cpp reads a file whole or in
// batches with them): where each meaning is among the fields, and a
// Builder that takes a point at a time from whichever form the body has
// (ascii, binary, binary_compressed).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/common.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "attribute_column.hpp"
#include "pcd_header.hpp"
#include "treecut/point_set.hpp"
#include "unit_normal.hpp"

namespace treecut::pcd {

// Where each meaning is: field indices, -1 when absent.
struct Roles {
  int xyz[3] = {-1, -1, -1};
  int normal[3] = {-1, -1, -1};
  int rgb = -1;                   // a packed colour (rgb, rgba)
  int channel[3] = {-1, -1, -1};  // separate red, green, blue fields
  std::vector<int> attributes;
  std::vector<std::string> not_kept;
};

/// The roles of H's fields.
Roles roles_of(const Header& h);

/// The value type of a field (PointAttribute::type).
ValueType value_type(const Field& f);

// The points, from values the body gives as value(point, field, element 0).
struct Builder {
  const Header& h;
  const Roles& r;
  PointSet points;
  std::vector<glm::dvec3> doubles;
  std::vector<glm::dvec3> channels;  // separate colour fields, as read
  std::vector<detail::AttributeColumn> attributes;

  Builder(const Header& header, const Roles& roles) : h(header), r(roles) {
    // Reserved only for what the body was checked to hold (parse()).
    const auto n = static_cast<std::size_t>(h.points);
    doubles.reserve(n);
    if (r.normal[0] >= 0) points.normals.reserve(n);
    if (r.rgb >= 0) points.colors.reserve(n);
    if (r.channel[0] >= 0) channels.reserve(n);
    for (const int a : r.attributes) {
      const Field& f = h.fields[static_cast<std::size_t>(a)];
      attributes.emplace_back(f.name, n, value_type(f));
    }
  }

  // VALUE(field) gives the field's first element as a double; RAW(field)
  // its 4 bytes (the packed colour), RAW64(field) an 8-byte integer's bits
  // (exactly, past 2^53 too).
  template <class Value, class Raw, class Raw64>
  void add(Value&& value, Raw&& raw, Raw64&& raw64) {
    doubles.emplace_back(value(r.xyz[0]), value(r.xyz[1]), value(r.xyz[2]));
    if (r.normal[0] >= 0) {
      points.normals.push_back(
          detail::unit_or_zero(value(r.normal[0]), value(r.normal[1]), value(r.normal[2])));
    }
    if (r.rgb >= 0) {
      const std::uint32_t c = raw(r.rgb);  // 0xAARRGGBB, as PCL packs it
      points.colors.emplace_back((c >> 16) & 255u, (c >> 8) & 255u, c & 255u, 255);
    }
    if (r.channel[0] >= 0)
      channels.emplace_back(value(r.channel[0]), value(r.channel[1]), value(r.channel[2]));
    for (std::size_t k = 0; k < attributes.size(); ++k) {
      const int f = r.attributes[k];
      const Field& x = h.fields[static_cast<std::size_t>(f)];
      const std::optional<std::uint64_t> bits =
          x.type != 'F' && x.size == 8 ? raw64(f) : std::nullopt;
      if (bits) {
        attributes[k].push_back_raw64(*bits);
      } else {
        attributes[k].push_back(value(f));
      }
    }
  }

  // Separate red, green and blue fields as the colour: floats in [0, 1],
  // integers in 0-255, or 16 bits (2-byte fields, or values past 255).
  void colours_from_channels() {
    if (channels.empty()) return;
    const Field& f = h.fields[static_cast<std::size_t>(r.channel[0])];
    double top = 0.0;
    for (const glm::dvec3& c : channels) {
      for (int k = 0; k < 3; ++k) {
        if (std::isfinite(c[k])) top = std::max(top, c[k]);
      }
    }
    const bool unit = f.type == 'F' && top <= 1.0;
    const bool sixteen = !unit && (f.size >= 2 && f.type != 'F' ? true : top > 255.0);
    auto clamp = [](double v, double hi) {
      return std::isfinite(v) ? std::clamp(v, 0.0, hi) : 0.0;
    };
    points.colors.resize(channels.size());
    if (sixteen) points.colors16.resize(channels.size());
    for (std::size_t i = 0; i < channels.size(); ++i) {
      const glm::dvec3 c = channels[i];
      if (sixteen) {
        const glm::u16vec3 deep(
            glm::round(glm::dvec3(clamp(c.x, 65535), clamp(c.y, 65535), clamp(c.z, 65535))));
        points.colors16[i] = deep;
        points.colors[i] = glm::u8vec4(glm::u16vec3(deep >> std::uint16_t(8)), 255);
      } else {
        const double s = unit ? 255.0 : 1.0;
        points.colors[i] =
            glm::u8vec4(glm::u8vec3(glm::round(glm::dvec3(clamp(c.x * s, 255), clamp(c.y * s, 255),
                                                          clamp(c.z * s, 255)))),
                        255);
      }
    }
    std::vector<glm::dvec3>().swap(channels);
  }
};

/// Points of H.points packed records at BODY (binary).
void read_packed(const unsigned char* body, const Header& h, Builder& b);

/// binary_compressed: the fields one after the other, each for every point.
void read_columns(const unsigned char* body, const Header& h, Builder& b);

/// ascii: a line a point, from H.body of FILE.
void read_ascii(std::string_view file, const Header& h, Builder& b);

/// binary_compressed: the LZF block (LEFT bytes at BODY), its sizes checked
/// against the file, the header and LZF's bound before anything is
/// allocated, unpacked to NEED bytes.
std::vector<unsigned char> unpack(const unsigned char* body, std::uint64_t left, const Header& h,
                                  std::uint64_t need);

/// The sensor's pose (VIEWPOINT) of an organized cloud, or of any cloud
/// whose pose is not the identity: the first view opens from it.
void set_viewpoint(const Header& h, PointSet& points);

}  // namespace treecut::pcd
