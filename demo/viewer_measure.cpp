// treecut view: picking and measuring (issue 30). Ctrl+click (or a script's
// `pick X Y`) takes the position the last frame drew at a pixel
// (Renderer::pick), the nearest point of a single model with its file
// coordinates and attributes, and, from the second pick on, the distance to
// the previous one, split into the height along the model's up axis and
// the horizontal rest.
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "viewer_app.hpp"

namespace treecut::cli {
namespace {

// The leaf (an input point) nearest to `p`: one pass over the nodes, on a
// click, not per frame (20 ms for 20 M points).
NodeId nearest_leaf(const Hierarchy& h, glm::vec3 p) {
  NodeId best = kNoNode;
  float best_d2 = std::numeric_limits<float>::infinity();
  for (NodeId n = h.level_begin(0); n < h.node_count(); ++n) {
    if (!h.is_leaf(n)) continue;
    const glm::vec3 d = h.center(n) - p;
    const float d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    if (d2 < best_d2) best_d2 = d2, best = n;
  }
  return best;
}

// From the first pick to the second: the distance, its part along the
// model's up axis and the horizontal rest.
struct Measure {
  double distance, height, horizontal;
};
Measure measure(glm::dvec3 a, glm::dvec3 b, glm::vec3 up) {
  const glm::dvec3 d = b - a;
  const double height = glm::dot(d, glm::dvec3(up));
  const double distance = glm::length(d);
  return {distance, height, std::sqrt(std::max(0.0, distance * distance - height * height))};
}

}  // namespace

void Viewer::pick_at(glm::ivec2 pixel) {
  const std::optional<glm::vec3> at = renderer_->pick(pixel, camera_);
  if (!at) {
    say("pick: nothing drawn there");
    std::printf("pick %d %d: nothing drawn there\n", pixel.x, pixel.y);
    return;
  }
  Pick p;
  // A single model: the nearest point, in the file's coordinates (double:
  // map coordinates), with its attributes.
  std::string what;
  if (!scene_.world && scene_.hierarchy) {
    const Hierarchy& h = *scene_.hierarchy;
    const glm::dvec3 o = h.frame().origin;
    p.file = o + glm::dvec3(*at);
    if (const NodeId leaf = nearest_leaf(h, *at); leaf != kNoNode) {
      const glm::dvec3 q = o + glm::dvec3(h.center(leaf));
      char line[160];
      std::snprintf(line, sizeof line, "point %.3f %.3f %.3f", q.x, q.y, q.z);
      what = line;
      const glm::u8vec4 c = h.arrays().color[leaf];
      std::snprintf(line, sizeof line, " rgb %d %d %d", c.x, c.y, c.z);
      what += line;
      for (const NodeAttribute& a : h.attributes()) {
        const float v = a.value(leaf);
        if (std::isnan(v)) continue;
        std::snprintf(line, sizeof line, " %s %.6g", a.name.c_str(), a.offset + double(v));
        what += line;
      }
    }
  } else {
    p.file = glm::dvec3(*at);
  }
  p.text = what;
  picks_.push_back(p);
  if (picks_.size() > 2) picks_.erase(picks_.begin());
  std::printf("pick %d %d: %.3f %.3f %.3f%s%s\n", pixel.x, pixel.y, p.file.x, p.file.y, p.file.z,
              what.empty() ? "" : ", nearest ", what.c_str());
  if (picks_.size() == 2) {
    const Measure m = measure(picks_[0].file, picks_[1].file, scene_.up);
    std::printf("measure   distance %.4f, height %+.4f, horizontal %.4f\n", m.distance, m.height,
                m.horizontal);
    char line[120];
    std::snprintf(line, sizeof line, "distance %.4f (height %+.4f, horizontal %.4f)", m.distance,
                  m.height, m.horizontal);
    say(line);
  } else {
    say("picked; Ctrl+click another point to measure");
  }
}

// The HUD's measure section: the last two picks and what lies between them.
void Viewer::measure_panel() {
  ImGui::TextDisabled("Ctrl+click a point (twice to measure)");
  for (std::size_t i = 0; i < picks_.size(); ++i) {
    const Pick& p = picks_[i];
    ImGui::Text("%c  %.3f %.3f %.3f", i == 0 ? 'A' : 'B', p.file.x, p.file.y, p.file.z);
    if (!p.text.empty()) ImGui::TextWrapped("   %s", p.text.c_str());
  }
  if (picks_.size() == 2) {
    const Measure m = measure(picks_[0].file, picks_[1].file, scene_.up);
    ImGui::Text("distance %.4f, height %+.4f", m.distance, m.height);
  }
  if (!picks_.empty() && ImGui::Button("clear")) picks_.clear();
}

}  // namespace treecut::cli
