// The up axis of a model from its points and normals (the rule is in up_axis.hpp).
#include "treecut/up_axis.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <vector>

namespace treecut {

namespace {

// The rule's constants, named as in the header comment.
constexpr float kQuantile = 0.002f;       // robust extent: 0.2% .. 99.8%
constexpr float kLayer = 0.02f;           // a ground layer: the lowest 2% of the extent
constexpr double kMinLayerShare = 0.035;  // ... holding at least 3.5% of the points
constexpr double kMinFootprint = 0.25;    // ... over a quarter of the cross-section
constexpr double kFacing = 0.1;           // mean n.d of normals that face one way
constexpr float kFlat = 0.5f;             // extent / next smallest extent of a flat model
constexpr double kLeaning = 0.015;        // mean n.d of normals that lean one way
constexpr double kLeaningMargin = 1.5;    // ... over the next direction

constexpr std::size_t kMaxSample = std::size_t{1} << 20;

std::string axis_name(int axis, bool negative) {
  return std::string(negative ? "-" : "") + "xyz"[axis];
}

std::string format(const char* pattern, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, pattern, value);
  return buffer;
}

UpAxis make(int axis, bool negative, std::string reason) {
  UpAxis up;
  up.axis = axis;
  up.negative = negative;
  up.reason = std::move(reason);
  return up;
}

// The value at quantile Q of one coordinate of the points.
float quantile(std::span<const glm::vec3> positions, int axis, float q) {
  std::vector<float> values(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) values[i] = positions[i][axis];
  const auto k = static_cast<std::size_t>(q * static_cast<float>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

// Per direction (axis, sign): the points in the layer at that end of the
// robust extent and the bounding rectangle of the layer across the other two
// axes; index 2 * axis + (negative ? 1 : 0).
struct Layer {
  std::size_t count = 0;
  glm::vec2 min{INFINITY}, max{-INFINITY};
};

// What one pass over the points gathers: the six layers and the sum of the
// defined normals (the mean normal of steps 2 and 4).
struct PointScan {
  std::array<Layer, 6> layers;
  glm::dvec3 flux{0.0};
  std::size_t defined = 0;
};

PointScan scan_points(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals,
                      const glm::vec3& lo, const glm::vec3& hi, const glm::vec3& extent) {
  const std::size_t n = positions.size();
  const bool with_normals = normals.size() == n;
  PointScan scan;
  for (std::size_t i = 0; i < n; ++i) {
    const glm::vec3& p = positions[i];
    for (int k = 0; k < 3; ++k) {
      if (!(extent[k] > 0.0f)) continue;
      const float band = kLayer * extent[k];
      const glm::vec2 across(p[(k + 1) % 3], p[(k + 2) % 3]);
      for (int side = 0; side < 2; ++side) {
        const bool in = side == 0 ? p[k] <= lo[k] + band : p[k] >= hi[k] - band;
        if (!in) continue;
        Layer& layer = scan.layers[static_cast<std::size_t>(2 * k + side)];
        ++layer.count;
        layer.min = glm::min(layer.min, across);
        layer.max = glm::max(layer.max, across);
      }
    }
    if (with_normals && normals[i] != glm::vec3(0.0f)) {
      scan.flux += glm::dvec3(normals[i]);
      ++scan.defined;
    }
  }
  return scan;
}

// Step 1: the direction whose layer holds the largest share of the `n`
// points among those that hold enough of them over enough of the
// cross-section (-1: none); its share in `best_share`.
int ground_layer(const std::array<Layer, 6>& layers, const glm::vec3& lo, const glm::vec3& hi,
                 const glm::vec3& extent, std::size_t n, double& best_share) {
  int best_layer = -1;
  best_share = 0.0;
  for (int d = 0; d < 6; ++d) {
    const int k = d / 2, u = (k + 1) % 3, v = (k + 2) % 3;
    const Layer& layer = layers[static_cast<std::size_t>(d)];
    if (layer.count == 0 || !(extent[u] > 0.0f) || !(extent[v] > 0.0f)) continue;
    // Clamped to the robust extent: an outlier does not widen the layer.
    const glm::vec2 cross_lo(lo[u], lo[v]), cross_hi(hi[u], hi[v]);
    const glm::vec2 size =
        glm::clamp(layer.max, cross_lo, cross_hi) - glm::clamp(layer.min, cross_lo, cross_hi);
    const double footprint =
        static_cast<double>(size.x) * size.y / (static_cast<double>(extent[u]) * extent[v]);
    const double share = static_cast<double>(layer.count) / static_cast<double>(n);
    // A ground or base is at one end: the layer at the other end holds at
    // most half as many points. The edge columns of a regular grid are
    // layers at both ends alike (a 20 x 20 terrain grid was laid on its side).
    const std::size_t opposite = layers[static_cast<std::size_t>(d ^ 1)].count;
    const bool one_sided = 2 * opposite <= layer.count;
    if (share >= kMinLayerShare && footprint >= kMinFootprint && one_sided && share > best_share) {
      best_share = share;
      best_layer = d;
    }
  }
  return best_layer;
}

// The rule on points and their normals; POINTS false: the centres are
// coarse nodes' (means), and rule 1 does not apply.
UpAxis detect(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals,
              bool points);

}  // namespace

glm::vec3 UpAxis::vector() const {
  glm::vec3 v(0.0f);
  v[axis] = negative ? -1.0f : 1.0f;
  return v;
}

std::string UpAxis::name() const {
  return axis_name(axis, negative);
}

std::optional<UpAxis> parse_up_axis(std::string_view text) {
  bool negative = false;
  if (!text.empty() && (text.front() == '-' || text.front() == '+')) {
    negative = text.front() == '-';
    text.remove_prefix(1);
  }
  if (text.size() != 1 || text[0] < 'x' || text[0] > 'z') return std::nullopt;
  return make(text[0] - 'x', negative, "");
}

UpAxis next_up_axis(const UpAxis& current) {
  return make((current.axis + 1) % 3, false, "");
}

UpAxis detect_up_axis(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals) {
  return detect(positions, normals, true);
}

namespace {

UpAxis detect(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals,
              bool points) {
  const std::size_t n = positions.size();
  if (n == 0) return make(2, false, "no points; default z");

  glm::vec3 lo, hi, extent;
  for (int k = 0; k < 3; ++k) {
    lo[k] = quantile(positions, k, kQuantile);
    hi[k] = quantile(positions, k, 1.0f - kQuantile);
    extent[k] = hi[k] - lo[k];
  }

  // 1. A ground or a base (points only: the centres of coarse nodes are
  // means, which pile up nowhere).
  const PointScan scan = scan_points(positions, normals, lo, hi, extent);
  double best_share = 0.0;
  if (const int best_layer = points ? ground_layer(scan.layers, lo, hi, extent, n, best_share) : -1;
      best_layer >= 0) {
    const int k = best_layer / 2;
    const bool negative = best_layer % 2 == 1;
    return make(k, negative,
                "a ground or base: " + format("%.1f", 100.0 * best_share) +
                    "% of the points lie in the lowest 2% along " + axis_name(k, negative));
  }

  // 2. and 4. need the mean normal; the strongest direction and the runner-up.
  const glm::dvec3 mean =
      scan.defined > 0 ? scan.flux / static_cast<double>(scan.defined) : glm::dvec3(0.0);
  int strongest = 0;
  for (int k = 1; k < 3; ++k) {
    if (std::fabs(mean[k]) > std::fabs(mean[strongest])) strongest = k;
  }
  double runner_up = 0.0;
  for (int k = 0; k < 3; ++k) {
    if (k != strongest) runner_up = std::max(runner_up, std::fabs(mean[k]));
  }
  const double facing = std::fabs(mean[strongest]);
  const bool facing_negative = mean[strongest] < 0.0;
  auto normal_reason = [&](const char* what) {
    return std::string(what) + (facing_negative ? "" : "+") +
           axis_name(strongest, facing_negative) + ": mean n." + "xyz"[strongest] + " = " +
           format("%.3f", mean[strongest]);
  };
  if (facing >= kFacing) {
    return make(strongest, facing_negative, normal_reason("normals face "));
  }

  // 3. A flat model.
  std::array<int, 3> order{0, 1, 2};
  std::sort(order.begin(), order.end(), [&](int a, int b) { return extent[a] < extent[b]; });
  if (extent[order[1]] > 0.0f && extent[order[0]] <= kFlat * extent[order[1]]) {
    return make(order[0], false,
                "flat along " + axis_name(order[0], false) + ": extent " +
                    format("%.2f", extent[order[0]] / extent[order[1]]) + " of the next smallest");
  }

  // 4. Normals that lean one way.
  if (facing >= kLeaning && facing >= kLeaningMargin * runner_up) {
    return make(strongest, facing_negative, normal_reason("normals lean to "));
  }
  return make(2, false, "no ground, base, flat extent or normal direction stands out; default z");
}

}  // namespace

UpAxis detect_up_axis(const Hierarchy& hierarchy) {
  const NodeRange all{0, hierarchy.node_count()};
  return detect_up_axis(hierarchy, std::span<const NodeRange>(&all, 1));
}

UpAxis detect_up_axis(const Hierarchy& hierarchy, std::span<const NodeRange> known) {
  if (hierarchy.empty()) return make(2, false, "no points; default z");
  if (hierarchy.frame().z_up)
    return make(2, false, "the file format says so (LAS: z is the height)");
  if (const std::optional<Viewpoint>& v = hierarchy.frame().viewpoint) {
    // A depth camera looks along its +z with +y down (PCL's convention):
    // up is its -y, turned by its orientation, to the nearest axis.
    const glm::dvec3 up = v->orientation * glm::dvec3(0.0, -1.0, 0.0);
    int k = 0;
    for (int a = 1; a < 3; ++a) {
      if (std::fabs(up[a]) > std::fabs(up[k])) k = a;
    }
    return make(k, up[k] < 0.0, "the sensor's viewpoint (PCD VIEWPOINT): its -y");
  }
  std::vector<glm::vec3> positions, normals;
  for (const NodeId node : sample_leaves(hierarchy, known, kMaxSample)) {
    positions.push_back(hierarchy.center(node));
    normals.push_back(hierarchy.normal(node));
  }
  if (positions.empty()) return make(2, false, "no node known; default z");
  // A part of the model (a paged model's root page): its coarse nodes.
  std::uint64_t held = 0;
  for (const NodeRange& r : known) held += r.count;
  return detect(positions, normals, held == hierarchy.node_count());
}

}  // namespace treecut
