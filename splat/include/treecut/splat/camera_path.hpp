// Camera paths: timed camera keys, recorded by `treecut view`, replayed by
// `treecut view --path` and `treecut render --path`. The text format is
// documented in docs/camera-paths.md:
//
//   treecut-camera-path 1
//   # time eye.x eye.y eye.z target.x target.y target.z up.x up.y up.z fov_y_deg
//   0.000 0.1 0.2 0.5 0 0.1 0 0 1 0 45
//
// Plain data, no GL; any thread.
#pragma once

#include <filesystem>
#include <glm/vec3.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/splat/camera.hpp"

namespace treecut::splat {

struct CameraKey {
  double time = 0.0;  ///< seconds from the start of the path, non-decreasing
  Camera camera;      ///< clip planes are not stored (the player fits them)
};

struct CameraPath {
  std::vector<CameraKey> keys;

  [[nodiscard]] bool empty() const { return keys.empty(); }
  /// Time of the last key (0 for zero or one key).
  [[nodiscard]] double duration() const { return keys.empty() ? 0.0 : keys.back().time; }
  /// The camera at time t (clamped to the path), eye/target/up/fov linearly
  /// interpolated between the surrounding keys. Requires !empty().
  [[nodiscard]] Camera at(double t) const;
  /// The path ends where it starts (an orbit): the time after its last key
  /// is its first key's view again.
  [[nodiscard]] bool loops() const;
  /// The time of frame F of FRAMES spread over the path: over [0, duration]
  /// for a path that goes somewhere, over [0, duration) for one that loops,
  /// so no two frames of an orbit look from one place (issue 43, item 18).
  [[nodiscard]] double frame_time(int f, int frames) const;
};

/// Parses the text format; throws InputError "NAME:LINE: problem" on any
/// malformed line, a number that is not finite or does not fit its type
/// (time: double, the rest: float), decreasing time, eye == target, an up
/// vector parallel to the view direction, fov outside (1, 170), or a missing
/// header.
CameraPath parse_camera_path(std::string_view text, const std::string& name);
std::string format_camera_path(const CameraPath& path);
/// File versions of the two above. load reads a regular file of at most
/// kTextInputLimit bytes (file_io.hpp: a FIFO, device or directory is refused
/// unopened) and throws InputError; save writes a temporary and renames it
/// (std::runtime_error naming the file on failure, nothing left behind).
CameraPath load_camera_path(const std::filesystem::path& file);
void save_camera_path(const std::filesystem::path& file, const CameraPath& path);

/// One turn about `up` around the model's bounding box in `seconds`, `keys`
/// keys (>= 2, the last equal to the first), at `elevation` radians.
CameraPath orbit_path(glm::vec3 bmin, glm::vec3 bmax, float aspect, double seconds, int keys,
                      glm::vec3 up = {0.0f, 1.0f, 0.0f}, float elevation = 0.35f);

}  // namespace treecut::splat
