#include "treecut/splat/camera_path.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "treecut/error.hpp"

namespace treecut::splat {

namespace {
constexpr std::string_view kHeader = "treecut-camera-path 1";

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return s.substr(first, last - first + 1);
}

// Splits on blanks and parses each token as a finite double.
bool parse_numbers(std::string_view line, std::vector<double>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= line.size()) break;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    double v = 0.0;
    const auto [ptr, ec] = std::from_chars(line.data() + i, line.data() + j, v);
    if (ec != std::errc() || ptr != line.data() + j || !std::isfinite(v)) return false;
    out.push_back(v);
    i = j;
  }
  return true;
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
  const glm::vec3 up = glm::mix(a.camera.up, b.camera.up, f);
  c.up = glm::length(up) > 1e-6f ? glm::normalize(up) : a.camera.up;
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
    const std::string_view line = trim(raw);
    if (line.empty() || line.front() == '#') continue;
    const auto where = name + ":" + std::to_string(line_no) + ": ";
    if (!header) {
      if (line != kHeader) throw InputError(where + "expected '" + std::string(kHeader) + "'");
      header = true;
      continue;
    }
    if (!parse_numbers(line, v)) throw InputError(where + "not a list of finite numbers");
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
    if (glm::length(k.camera.eye - k.camera.target) <= 0.0f) {
      throw InputError(where + "eye and target coincide");
    }
    if (glm::length(k.camera.up) <= 0.0f) throw InputError(where + "zero up vector");
    if (!(k.camera.fov_y_deg > 1.0f && k.camera.fov_y_deg < 170.0f)) {
      throw InputError(where + "fov_y_deg outside (1, 170)");
    }
    k.camera.up = glm::normalize(k.camera.up);
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
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string() + ": cannot open camera path");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  if (text.size() > (64u << 20))
    throw InputError(file.string() + ": camera path larger than 64 MiB");
  return parse_camera_path(text, file.string());
}

void save_camera_path(const std::filesystem::path& file, const CameraPath& path) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << format_camera_path(path);
  if (!out) throw std::runtime_error(file.string() + ": could not write camera path");
}

CameraPath orbit_path(glm::vec3 bmin, glm::vec3 bmax, float aspect, double seconds, int keys,
                      glm::vec3 up, float elevation) {
  keys = std::max(keys, 2);
  CameraPath path;
  for (int i = 0; i < keys; ++i) {
    const double f = double(i) / double(keys - 1);
    CameraKey k;
    k.time = f * seconds;
    k.camera = orbit_camera(bmin, bmax, aspect, static_cast<float>(f * 2.0 * std::numbers::pi),
                            elevation, up);
    path.keys.push_back(k);
  }
  return path;
}

}  // namespace treecut::splat
