// The walkthroughs of the scenes (generate.hpp, scene_walkthrough): computed,
// not typed, so `treecut gen KIND --walk FILE` reproduces
// assets/paths/KIND_walk.campath exactly and a change of the layout's lanes
// moves the path with it.
#include <algorithm>
#include <cmath>
#include <functional>
#include <glm/geometric.hpp>
#include <numbers>

#include "treecut/error.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::tools {

namespace {

struct Route {
  float y = 0.5f;  // the walk goes east along y = -y, north along x = x, west along y = +y
  float x = 0.5f;
  float eye = 0.008f;   // eye height
  float speed = 0.08f;  // units per second
  float ahead = 0.15f;  // the target: this far ahead along the route, at eye height
};

Route route(ModelKind kind) {
  switch (kind) {
    case ModelKind::City: {
      // Streets at -1 + k * 0.25: y = -0.5, 0.5 and x = 0.5 are streets.
      const CityLayout c;
      return {1.0f - 2.0f * c.block_pitch, 1.0f - 2.0f * c.block_pitch, walk_eye_height(kind),
              0.08f, 0.15f};
    }
    case ModelKind::Field: {
      // Lanes at -1 + k * 0.2: y = -0.4, 0.4 and x = 0.6.
      const FieldLayout f;
      return {1.0f - 3.0f * f.cell_pitch, 1.0f - 2.0f * f.cell_pitch, walk_eye_height(kind), 0.07f,
              0.10f};
    }
    case ModelKind::Plant: {
      // Aisles at -1 + k / 3: y = -1/3, 1/3 and x = 1/3 (the racks above).
      const PlantLayout p;
      return {1.0f - 2.0f * p.cell_pitch, 1.0f - 2.0f * p.cell_pitch, walk_eye_height(kind), 0.06f,
              0.10f};
    }
    default:
      throw InputError("no walkthrough for this model kind (city, field or plant)");
  }
}

float smooth(float t) {
  return t * t * (3.0f - 2.0f * t);
}

// The route as a polyline from the west edge, with the last leg extended past
// its end so the look-ahead target never meets the eye.
struct Polyline {
  std::vector<glm::vec3> p;
  std::vector<float> s;  // arc length at each vertex
  glm::vec3 at(float d) const {
    for (std::size_t i = 1; i < p.size(); ++i)
      if (d <= s[i] || i + 1 == p.size()) {
        const float len = s[i] - s[i - 1];
        return p[i - 1] + (d - s[i - 1]) / len * (p[i] - p[i - 1]);
      }
    return p.back();
  }
};

// The five segments of a walkthrough along `line` (walk_length long, then
// its target's run-out): the overview, an arc about the whole scene; over to
// above the start of the walk; straight down to eye level; the walk at
// `speed` looking `ahead` along the route; up again and back to the
// overview. Keys every 0.1 s; `arc(deg)` is the overview's eye at an angle,
// `centre` what it looks at, `high` the height above the route's ends.
std::vector<WalkKey> five_segments(const Polyline& line, float walk_length, float ahead,
                                   float speed, glm::vec3 centre, float high,
                                   const std::function<glm::vec3(float)>& arc) {
  std::vector<WalkKey> keys;
  double t0 = 0.0;
  // One segment: `seconds` long, keys every 0.1 s, the camera from f(0) to f(1).
  auto segment = [&](double seconds, auto&& f) {
    const int steps = std::max(1, static_cast<int>(std::lround(seconds * 10.0)));
    for (int k = keys.empty() ? 0 : 1; k <= steps; ++k) {
      WalkKey key;
      key.time = t0 + seconds * k / steps;
      f(static_cast<float>(k) / static_cast<float>(steps), key);
      keys.push_back(key);
    }
    t0 += seconds;
  };
  const glm::vec3 start = line.at(0.0f), start_look = line.at(ahead);
  const glm::vec3 end = line.at(walk_length), end_look = line.at(walk_length + ahead);
  const glm::vec3 above_start(start.x, start.y, high), above_end(end.x, end.y, high);
  // 1. The overview: an arc about the whole scene.
  segment(4.0, [&](float t, WalkKey& k) {
    k.eye = arc(-60.0f - 80.0f * t);
    k.target = centre;
  });
  // 2. Over to above the start of the walk, looking down the first street.
  segment(4.0, [&](float t, WalkKey& k) {
    const float e = smooth(t);
    k.eye = glm::mix(arc(-140.0f), above_start, e);
    k.target = glm::mix(centre, start_look, e);
  });
  // 3. Straight down to eye level (over a lane: nothing in the way).
  segment(3.0, [&](float t, WalkKey& k) {
    k.eye = glm::mix(above_start, start, smooth(t));
    k.target = start_look;
  });
  // 4. The walk, at constant speed, looking ahead along the route.
  segment(walk_length / speed, [&](float t, WalkKey& k) {
    const float d = t * walk_length;
    k.eye = line.at(d);
    k.target = line.at(d + ahead);
  });
  // 5. Up again, and back to the overview.
  segment(3.0, [&](float t, WalkKey& k) {
    k.eye = glm::mix(end, above_end, smooth(t));
    k.target = end_look;
  });
  segment(4.0, [&](float t, WalkKey& k) {
    const float e = smooth(t);
    k.eye = glm::mix(above_end, arc(140.0f), e);
    k.target = glm::mix(end_look, centre, e);
  });
  return keys;
}

}  // namespace

float walk_eye_height(ModelKind kind) {
  switch (kind) {
    case ModelKind::City:
      return 0.008f;  // 4 m: a bus's upper deck
    case ModelKind::Field:
      return 0.025f;  // a third of a copy's height
    case ModelKind::Plant:
      return 0.010f;  // below the racks (lowest pipe bottom 0.034)
    default:
      return 0.0f;
  }
}

std::vector<WalkKey> scene_walkthrough(ModelKind kind) {
  const Route r = route(kind);
  const float h = r.eye;
  Polyline line;
  line.p = {{-1.0f, -r.y, h}, {r.x, -r.y, h}, {r.x, r.y, h}, {-1.0f, r.y, h}};
  line.s = {0.0f};
  for (std::size_t i = 1; i < line.p.size(); ++i)
    line.s.push_back(line.s.back() + glm::length(line.p[i] - line.p[i - 1]));
  const float walk_length = line.s.back();
  // Past the end: the target keeps going west, out of the scene.
  line.p.push_back(line.p.back() + glm::vec3(-1.0f, 0.0f, 0.0f));
  line.s.push_back(walk_length + 1.0f);

  const glm::vec3 centre(0.0f, 0.0f, 0.05f);
  const float radius = 2.4f, height = 1.5f, high = 0.7f;
  auto arc = [&](float deg) {
    const float a = deg * std::numbers::pi_v<float> / 180.0f;
    return glm::vec3(radius * std::cos(a), radius * std::sin(a), height);
  };
  return five_segments(line, walk_length, r.ahead, r.speed, centre, high, arc);
}

std::vector<WalkKey> route_walkthrough(glm::vec2 lo, glm::vec2 hi, float top,
                                       const std::vector<glm::vec2>& route, float eye, float speed,
                                       float ahead) {
  if (route.size() < 2) throw InputError("route_walkthrough: a route needs at least two points");
  if (!(hi.x > lo.x && hi.y > lo.y) || !(speed > 0.0f) || !(eye > 0.0f))
    throw InputError("route_walkthrough: empty extent, or no speed or eye height");
  // The same five segments as scene_walkthrough, sized by the scene's extent
  // instead of the unit square: a scene of any number of objects gets a path.
  Polyline line;
  for (const glm::vec2 p : route) line.p.emplace_back(p.x, p.y, eye);
  line.s = {0.0f};
  for (std::size_t i = 1; i < line.p.size(); ++i)
    line.s.push_back(line.s.back() + glm::length(line.p[i] - line.p[i - 1]));
  const float walk_length = line.s.back();
  if (!(walk_length > 0.0f)) throw InputError("route_walkthrough: the route has no length");
  // Past the end the target keeps going the way of the last leg.
  const glm::vec3 last = glm::normalize(line.p.back() - line.p[line.p.size() - 2]);
  line.p.push_back(line.p.back() + (ahead + 1.0f) * last);
  line.s.push_back(walk_length + ahead + 1.0f);

  const glm::vec2 mid = 0.5f * (lo + hi);
  const float half = 0.5f * glm::length(hi - lo);
  const glm::vec3 centre(mid.x, mid.y, 0.25f * top);
  const float radius = 1.6f * half, height = top + 1.0f * half, high = top + 0.35f * half;
  auto arc = [&](float deg) {
    const float a = deg * std::numbers::pi_v<float> / 180.0f;
    return glm::vec3(mid.x + radius * std::cos(a), mid.y + radius * std::sin(a), height);
  };
  return five_segments(line, walk_length, ahead, speed, centre, high, arc);
}

}  // namespace treecut::tools
