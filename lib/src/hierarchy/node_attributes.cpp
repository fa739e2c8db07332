// Attribute summaries per hierarchy node (node_attributes.hpp).
#include "node_attributes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "bottom_up.hpp"
#include "treecut/parallel.hpp"

namespace treecut::detail {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// The point-weighted mean of the children's finite values.
float mean_of_children(const std::vector<float>& v, std::size_t c0, unsigned cc,
                       std::span<const std::uint32_t> point_count) {
  double sum = 0.0, weight = 0.0;
  for (std::size_t c = c0; c < c0 + cc; ++c) {
    if (std::isnan(v[c])) continue;
    sum += double(point_count[c]) * double(v[c]);
    weight += double(point_count[c]);
  }
  return weight > 0.0 ? static_cast<float>(sum / weight) : kNaN;
}

// The children's value with the most points behind it (ties: the smaller
// value, so the result does not depend on the children's order).
float mode_of_children(const std::vector<float>& v, std::size_t c0, unsigned cc,
                       std::span<const std::uint32_t> point_count) {
  float best = kNaN;
  std::uint64_t best_weight = 0;
  for (std::size_t c = c0; c < c0 + cc; ++c) {
    if (std::isnan(v[c])) continue;
    std::uint64_t weight = 0;
    for (std::size_t k = c0; k < c0 + cc; ++k) {
      if (v[k] == v[c]) weight += point_count[k];
    }
    if (weight > best_weight || (weight == best_weight && v[c] < best)) {
      best = v[c];
      best_weight = weight;
    }
  }
  return best;
}

}  // namespace

namespace {

// The offset of the node values: the points' own where their floats are
// exact (classes and intensities stay whole numbers), else the middle of
// their range in whole units (a GPS time near 245,380 s keeps its
// microseconds as a float within a few seconds of it).
double node_offset(const PointAttribute& p, double lo, double hi) {
  if (!p.values.empty() || !(lo <= hi)) return p.offset;
  const double mid = std::round(0.5 * lo + 0.5 * hi);
  return std::fabs(mid) < 16777216.0 && lo == std::round(lo) && hi == std::round(hi) ? 0.0 : mid;
}

}  // namespace

std::vector<OwnedAttribute> fill_leaf_values(std::vector<PointAttribute>& points,
                                             std::span<const NodeId> leaf_point,
                                             std::span<const std::uint8_t> child_count,
                                             unsigned threads) {
  std::vector<OwnedAttribute> out;
  out.reserve(points.size());
  const std::size_t M = child_count.size();
  for (PointAttribute& p : points) {
    OwnedAttribute& a = out.emplace_back();
    a.name = p.name;
    a.kind = p.kind;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    const std::size_t n = p.stored();
    for (std::size_t i = 0; i < n; ++i) {
      const double v = p.value(i);
      if (!std::isnan(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    }
    if (p.is_constant() && !std::isnan(p.constant)) lo = hi = p.constant;
    a.min = lo <= hi ? lo : std::numeric_limits<double>::quiet_NaN();
    a.max = lo <= hi ? hi : std::numeric_limits<double>::quiet_NaN();
    a.offset = node_offset(p, lo, hi);
    if (p.is_constant()) {
      // Stored once: an all-ground tile is information, not 4 bytes a node.
      a.offset = std::isnan(p.constant) || std::fabs(p.constant) < 16777216.0
                     ? 0.0
                     : std::round(p.constant);
      a.constant = static_cast<float>(p.constant - a.offset);
      continue;
    }
    a.values.resize(M);
    parallel_for(
        M,
        [&](std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i) {
            if (child_count[i] != 0) continue;
            const double v = p.value(leaf_point[i]);
            a.values[i] = std::isnan(v) ? kNaN : static_cast<float>(v - a.offset);
          }
        },
        threads);
    // Released: the peak stays one copy.
    std::vector<float>().swap(p.values);
    std::vector<double>().swap(p.wide);
  }
  points.clear();
  return out;
}

void fill_interior_values(std::vector<OwnedAttribute>& attributes,
                          std::span<const std::uint8_t> child_count,
                          std::span<const NodeId> first_child,
                          std::span<const std::uint32_t> point_count,
                          std::span<const NodeId> level_begin, unsigned threads) {
  for (OwnedAttribute& a : attributes) {
    if (a.values.empty()) continue;  // constant
    const bool mode = a.kind == AttributeKind::category;
    for_each_interior_bottom_up(
        level_begin, child_count, threads,
        [&](std::size_t i) {
          a.values[i] =
              mode ? mode_of_children(a.values, first_child[i], child_count[i], point_count)
                   : mean_of_children(a.values, first_child[i], child_count[i], point_count);
        },
        [] {});
  }
}

std::vector<NodeAttribute> node_attribute_views(const std::vector<OwnedAttribute>& attributes) {
  std::vector<NodeAttribute> out;
  for (const OwnedAttribute& a : attributes) {
    out.push_back({a.name, a.kind, a.offset, a.min, a.max, a.values, a.constant});
  }
  return out;
}

}  // namespace treecut::detail
