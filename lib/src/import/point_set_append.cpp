// PointSet::append (point_set.hpp): the points of another file of the same
// cloud after these (issue 44: many tiles are one model), every array in
// step and every attribute at the precision both files allow.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "attribute_column.hpp"
#include "treecut/point_set.hpp"

namespace treecut {

namespace {

// Per-point arrays that both sets have are joined; one that only one set
// has is dropped (normals, radii and curvature are then estimated for all,
// as for a file without them).
template <class T>
void join_or_drop(std::vector<T>& into, std::size_t into_points, std::vector<T>&& more,
                  std::size_t more_points) {
  const bool have = into.size() == into_points && into_points != 0;
  const bool more_have = more.size() == more_points && more_points != 0;
  if (have && more_have) {
    into.insert(into.end(), more.begin(), more.end());
  } else {
    std::vector<T>().swap(into);
  }
}

// The common encoding of one attribute in two files: the same type, scale
// and base where they agree, else doubles (the values are already the
// file's, scaled).
void widen(PointAttribute& a, const PointAttribute& b) {
  if (a.type != b.type) {
    const bool both_integers = is_integer(a.type) && is_integer(b.type);
    a.type = both_integers && value_size(a.type) != value_size(b.type) &&
                     is_signed(a.type) == is_signed(b.type)
                 ? (value_size(a.type) > value_size(b.type) ? a.type : b.type)
                 : ValueType::f64;
  }
  if (a.scale != b.scale || a.base != b.base) a.type = ValueType::f64, a.scale = 1.0, a.base = 0.0;
  if (a.no_data != b.no_data) a.no_data.reset();
}

// A's values then B's (an absent one: NaN at each of its points).
PointAttribute join_attribute(const PointAttribute* a, std::size_t a_points,
                              const PointAttribute* b, std::size_t b_points) {
  PointAttribute shape = a ? *a : *b;
  if (a && b) widen(shape, *b);
  shape.values.clear(), shape.wide.clear(), shape.integers.clear();
  detail::AttributeColumn column(shape.name, a_points + b_points, shape.type, shape.scale,
                                 shape.base, shape.no_data);
  const bool integers = (a && !a->integers.empty()) || (b && !b->integers.empty());
  const auto push = [&](const PointAttribute* from, std::size_t points) {
    for (std::size_t i = 0; i < points; ++i) {
      if (!from) {
        column.push_back(std::numeric_limits<double>::quiet_NaN());
      } else if (integers && !from->integers.empty()) {
        column.push_back_raw64(static_cast<std::uint64_t>(from->integers[i]));
      } else if (integers) {
        // The other file's values are integers a double holds exactly.
        column.push_back_raw64(
            static_cast<std::uint64_t>(static_cast<std::int64_t>(from->value(i))));
      } else {
        column.push_back(from->value(i));
      }
    }
  };
  push(a, a_points);
  push(b, b_points);
  PointAttribute joined = column.take();
  joined.kind = shape.kind;
  return joined;
}

bool same(double x, double y) {
  return x == y || (std::isnan(x) && std::isnan(y));
}

// A's values followed by B's (none: NaN), in place where A varies already:
// amortized over a folder of tiles, each value is touched once, not once a
// tile (a 16-tile survey's read took 32 s with every join re-encoding all).
// A constant that starts to vary, and 64-bit integers, are re-encoded.
void extend(PointAttribute& a, std::size_t n, const PointAttribute* b, std::size_t m) {
  const double b_constant = b ? b->constant : std::numeric_limits<double>::quiet_NaN();
  if (a.is_constant() && (!b || b->is_constant()) && same(a.constant, b_constant)) return;
  if (a.is_constant() || !a.integers.empty() || (b && !b->integers.empty())) {
    a = join_attribute(&a, n, b, m);
    return;
  }
  if (b) widen(a, *b);
  const auto value = [&](std::size_t i) {
    return b ? b->value(i) : std::numeric_limits<double>::quiet_NaN();
  };
  // The usual tiles: both floats from one offset (classes, intensities),
  // or both doubles (GPS times), joined as they are.
  if (b && !a.values.empty() && !b->values.empty() && a.offset == b->offset) {
    a.values.insert(a.values.end(), b->values.begin(), b->values.end());
    return;
  }
  if (b && !a.wide.empty() && !b->wide.empty()) {
    a.wide.insert(a.wide.end(), b->wide.begin(), b->wide.end());
    return;
  }
  std::size_t i = 0;
  if (!a.values.empty()) {
    // Floats relative to A's offset while each gives its value back.
    for (; i < m; ++i) {
      const double v = value(i);
      const auto f = static_cast<float>(v - a.offset);
      if (!std::isnan(v) && !(std::isfinite(f) && a.offset + double(f) == v)) break;
      a.values.push_back(std::isnan(v) ? std::numeric_limits<float>::quiet_NaN() : f);
    }
    if (i == m) return;
    // One that does not: doubles for all from now on.
    a.wide.reserve(a.values.size() + (m - i));
    for (const float f : a.values) a.wide.push_back(a.offset + double(f));
    std::vector<float>().swap(a.values);
    a.offset = 0.0;
  }
  for (; i < m; ++i) a.wide.push_back(value(i));
}

const PointAttribute* find(const std::vector<PointAttribute>& all, const std::string& name) {
  const auto it =
      std::find_if(all.begin(), all.end(), [&](const PointAttribute& a) { return a.name == name; });
  return it == all.end() ? nullptr : &*it;
}

}  // namespace

void PointSet::append(PointSet&& more) {
  const std::size_t n = size(), m = more.size();
  if (n == 0 && attributes.empty()) {
    *this = std::move(more);
    return;
  }
  // More's positions move to this origin (floats: within the cloud's reach
  // of it; open_model says so past 32,768 units).
  const glm::dvec3 shift = more.frame.origin - frame.origin;
  if (!exact_positions.empty() || !more.exact_positions.empty()) {
    const auto exact = [](PointSet& ps) {
      if (!ps.exact_positions.empty()) return;
      ps.exact_positions.reserve(ps.size());
      for (const glm::vec3& p : ps.positions)
        ps.exact_positions.push_back(ps.frame.origin + glm::dvec3(p));
    };
    exact(*this), exact(more);
    exact_positions.insert(exact_positions.end(), more.exact_positions.begin(),
                           more.exact_positions.end());
  }
  for (const glm::vec3& p : more.positions) positions.emplace_back(glm::dvec3(p) + shift);
  join_or_drop(normals, n, std::move(more.normals), m);
  join_or_drop(radii, n, std::move(more.radii), m);
  join_or_drop(curvature, n, std::move(more.curvature), m);
  // Colours: a file without them is the grey of an uncoloured file; the 16
  // bits where either set has them (8 bits times 257 for the other).
  const glm::u8vec4 grey(200, 200, 200, 255);
  if (has_colors() || more.has_colors()) {
    if (!colors16.empty() || !more.colors16.empty()) {
      for (PointSet* ps : {this, &more}) {
        if (!ps->colors16.empty()) continue;
        ps->colors16.reserve(ps->size());
        for (std::size_t i = 0; i < ps->size(); ++i)
          ps->colors16.push_back(glm::u16vec3(ps->has_colors() ? ps->colors[i] : grey) *
                                 std::uint16_t(257));
      }
      colors16.insert(colors16.end(), more.colors16.begin(), more.colors16.end());
    }
    colors.resize(n, grey);
    if (more.has_colors()) {
      colors.insert(colors.end(), more.colors.begin(), more.colors.end());
    } else {
      colors.resize(n + m, grey);
    }
  }
  const auto base = static_cast<std::uint32_t>(n);
  for (const glm::uvec3& t : more.triangles) triangles.push_back(t + base);
  // Attributes by name, this set's first and then more's new ones.
  const std::size_t had = attributes.size();
  for (const PointAttribute& b : more.attributes) {
    if (attributes.size() == kMaxAttributes) break;
    const auto known = std::find_if(attributes.begin(), attributes.begin() + long(had),
                                    [&](const PointAttribute& a) { return a.name == b.name; });
    if (known == attributes.begin() + long(had))
      attributes.push_back(join_attribute(nullptr, n, &b, m));
  }
  for (std::size_t k = 0; k < had; ++k)
    extend(attributes[k], n, find(more.attributes, attributes[k].name), m);
  if (frame.resolution != more.frame.resolution || frame.grid_offset != more.frame.grid_offset)
    frame.resolution = glm::dvec3(0.0), frame.grid_offset = glm::dvec3(0.0);
  frame.normals_estimated = frame.normals_estimated || more.frame.normals_estimated;
}

}  // namespace treecut
