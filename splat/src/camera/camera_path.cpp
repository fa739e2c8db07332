#include "treecut/splat/camera_path.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/point_set.hpp"

namespace treecut::splat {

namespace {
constexpr std::string_view kHeader = "treecut-camera-path 1";
constexpr const char* kFields[11] = {"time",     "eye.x", "eye.y", "eye.z", "target.x", "target.y",
                                     "target.z", "up.x",  "up.y",  "up.z",  "fov_y_deg"};
// sin(0.1 degree): an up vector closer than this to the view direction leaves
// the camera's roll undefined (lookAt's cross product vanishes: blank frames).
constexpr float kMinUpAngleSin = 1.7453e-3f;

// Splits on blanks and parses each token as a finite double. Returns the
// problem ("" when every token is a finite number); a token that is not a
// number, that overflows a double, or is inf/nan is named in the message.
std::string parse_numbers(std::string_view line, std::vector<double>& out) {
  out.clear();
  for (const std::string_view token : split_blanks(line)) {
    double v = 0.0;
    const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    const std::string what = out.size() < 11 ? std::string(kFields[out.size()]) + " " : "";
    const std::string shown = printable_excerpt(token);
    if (ec == std::errc::result_out_of_range) return what + "'" + shown + "' is out of range";
    if (ec != std::errc() || ptr != token.data() + token.size())
      return what + "'" + shown + "' is not a number";
    if (!std::isfinite(v)) return what + "'" + shown + "' is not a finite number";
    // Everything but the time is stored as a float: a double past FLT_MAX
    // would become infinity without a word. Eye and target are points of the
    // model's space, within the coordinate limit (their squared distance must
    // fit a float).
    if (out.size() >= 1 && out.size() <= 6 &&
        static_cast<float>(std::min(std::abs(v), 1e30)) > kMaxCoordinate)
      return what + "'" + shown + "' is out of range (coordinates are at most 1e18 in magnitude)";
    if (out.size() >= 1 && std::abs(v) > double(std::numeric_limits<float>::max()))
      return what + "'" + shown + "' is out of range (single precision)";
    out.push_back(v);
  }
  return {};
}
}  // namespace

Camera CameraPath::at(double t) const {
  if (keys.empty()) throw std::logic_error("CameraPath::at on an empty path");
  if (t <= keys.front().time) return keys.front().camera;
  if (t >= keys.back().time) return keys.back().camera;
  const auto it = std::upper_bound(keys.begin(), keys.end(), t,
                                   [](double v, const CameraKey& k) { return v < k.time; });
  const CameraKey& b = *it;
  const CameraKey& a = *(it - 1);
  const double span = b.time - a.time;
  const float f = span > 0.0 ? static_cast<float>((t - a.time) / span) : 1.0f;
  Camera c = a.camera;
  c.eye = glm::mix(a.camera.eye, b.camera.eye, f);
  c.target = glm::mix(a.camera.target, b.camera.target, f);
  // Each key's up is checked against its own view direction on load, but a
  // blend of two keys can still be parallel to the blended direction (or
  // vanish): then the key's up that is furthest from parallel keeps the roll.
  const glm::vec3 dir = c.target - c.eye;
  const float dir_len = glm::length(dir);
  auto off_axis = [&](glm::vec3 u) {
    const float len = glm::length(u);
    if (!(len > 1e-6f) || !(dir_len > 0.0f)) return 0.0f;
    return glm::length(glm::cross(dir / dir_len, u / len));
  };
  const glm::vec3 mixed = glm::mix(a.camera.up, b.camera.up, f);
  if (off_axis(mixed) >= kMinUpAngleSin) {
    c.up = glm::normalize(mixed);
  } else {
    c.up = off_axis(a.camera.up) >= off_axis(b.camera.up) ? a.camera.up : b.camera.up;
  }
  c.fov_y_deg = glm::mix(a.camera.fov_y_deg, b.camera.fov_y_deg, f);
  return c;
}

CameraPath parse_camera_path(std::string_view text, const std::string& name) {
  CameraPath path;
  bool header = false;
  int line_no = 0;
  std::vector<double> v;
  while (!text.empty()) {
    const auto nl = text.find('\n');
    const std::string_view raw = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
    ++line_no;
    const std::string_view line = trim_blanks(raw);
    if (line.empty() || line.front() == '#') continue;
    const auto where = name + ":" + std::to_string(line_no) + ": ";
    if (!header) {
      if (line != kHeader) throw InputError(where + "expected '" + std::string(kHeader) + "'");
      header = true;
      continue;
    }
    if (const std::string problem = parse_numbers(line, v); !problem.empty())
      throw InputError(where + problem);
    if (v.size() != 11) {
      throw InputError(where + "expected 11 numbers (time, eye, target, up, fov), got " +
                       std::to_string(v.size()));
    }
    CameraKey k;
    k.time = v[0];
    k.camera.eye = glm::vec3(v[1], v[2], v[3]);
    k.camera.target = glm::vec3(v[4], v[5], v[6]);
    k.camera.up = glm::vec3(v[7], v[8], v[9]);
    k.camera.fov_y_deg = static_cast<float>(v[10]);
    if (k.time < 0.0) throw InputError(where + "negative time");
    if (!path.keys.empty() && k.time < path.keys.back().time) {
      throw InputError(where + "time goes backwards");
    }
    // In double, from the floats that are kept: no length of a valid key
    // overflows (an up of 1e30 is as good as one of 1).
    const glm::dvec3 eye(k.camera.eye), target(k.camera.target), up(k.camera.up);
    const glm::dvec3 view = target - eye;
    const double dist = glm::length(view);
    // Within a few float steps of each other the direction is noise.
    const double scale = std::max(glm::length(eye), glm::length(target));
    if (!(dist > 4.0 * std::numeric_limits<float>::epsilon() * scale) ||
        dist < std::numeric_limits<float>::min()) {
      throw InputError(where + "eye and target coincide");
    }
    const double up_len = glm::length(up);
    if (!(up_len >= std::numeric_limits<float>::min())) throw InputError(where + "zero up vector");
    if (glm::length(glm::cross(view / dist, up / up_len)) < kMinUpAngleSin)
      throw InputError(where + "up vector is parallel to the view direction (target - eye)");
    if (!(k.camera.fov_y_deg > 1.0f && k.camera.fov_y_deg < 170.0f)) {
      throw InputError(where + "fov_y_deg outside (1, 170)");
    }
    k.camera.up = glm::vec3(up / up_len);
    path.keys.push_back(k);
  }
  if (!header) throw InputError(name + ": empty camera path (no '" + std::string(kHeader) + "')");
  if (path.keys.empty()) throw InputError(name + ": camera path has no keys");
  return path;
}

std::string format_camera_path(const CameraPath& path) {
  std::ostringstream out;
  out.precision(9);
  out << kHeader << "\n";
  out << "# time eye.x eye.y eye.z target.x target.y target.z up.x up.y up.z fov_y_deg\n";
  for (const CameraKey& k : path.keys) {
    const Camera& c = k.camera;
    out << k.time << ' ' << c.eye.x << ' ' << c.eye.y << ' ' << c.eye.z << ' ' << c.target.x << ' '
        << c.target.y << ' ' << c.target.z << ' ' << c.up.x << ' ' << c.up.y << ' ' << c.up.z << ' '
        << c.fov_y_deg << "\n";
  }
  return out.str();
}

CameraPath load_camera_path(const std::filesystem::path& file) {
  // Refuses a FIFO, a device or a directory without opening it, and reads at
  // most kTextInputLimit bytes (a path of /dev/zero would otherwise grow forever).
  return parse_camera_path(read_text_file(file, kTextInputLimit), quoted_name(file));
}

bool CameraPath::loops() const {
  if (keys.size() < 3) return false;
  const Camera &a = keys.front().camera, &b = keys.back().camera;
  const float scale = std::max(glm::length(a.eye - a.target), 1e-6f);
  return glm::distance(a.eye, b.eye) <= 1e-5f * scale &&
         glm::distance(a.target, b.target) <= 1e-5f * scale && a.fov_y_deg == b.fov_y_deg;
}

double CameraPath::frame_time(int f, int frames) const {
  if (frames <= 1) return 0.0;
  return duration() * double(f) / double(loops() ? frames : frames - 1);
}

void save_camera_path(const std::filesystem::path& file, const CameraPath& path) {
  // Temporary + rename: a full disk leaves no truncated path that looks complete.
  write_file_atomically(file, format_camera_path(path));
}

CameraPath orbit_path(glm::vec3 bmin, glm::vec3 bmax, float aspect, double seconds, int keys,
                      glm::vec3 up, float elevation) {
  keys = std::max(keys, 2);
  CameraPath path;
  float distance = 0.0f;
  for (int i = 0; i < keys; ++i) {
    const double f = double(i) / double(keys - 1);
    CameraKey k;
    k.time = f * seconds;
    k.camera = orbit_camera(bmin, bmax, aspect, static_cast<float>(f * 2.0 * std::numbers::pi),
                            elevation, up);
    distance = std::max(distance, glm::distance(k.camera.eye, k.camera.target));
    path.keys.push_back(k);
  }
  // One distance all the way round: the farthest any direction needs, so
  // the model does not breathe as the orbit turns.
  for (CameraKey& k : path.keys) {
    const float moved = distance - glm::distance(k.camera.eye, k.camera.target);
    k.camera.eye = k.camera.target + k.camera.forward() * -distance;
    k.camera.near_plane += moved, k.camera.far_plane += moved;
  }
  return path;
}

}  // namespace treecut::splat
