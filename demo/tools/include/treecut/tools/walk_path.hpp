// A walkthrough (generate.hpp) as the View's camera path. Header-only, so
// treecut::tools itself needs no renderer: whoever plays a walk links
// treecut::splat already.
#pragma once

#include <vector>

#include "treecut/splat/camera_path.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::tools {

/// The camera path of a walkthrough, key for key (the player fits the clip
/// planes).
inline splat::CameraPath walk_path(const std::vector<WalkKey>& keys) {
  splat::CameraPath path;
  path.keys.reserve(keys.size());
  for (const WalkKey& k : keys) {
    splat::CameraKey key;
    key.time = k.time;
    key.camera.eye = k.eye;
    key.camera.target = k.target;
    key.camera.up = k.up;
    key.camera.fov_y_deg = k.fov_deg;
    path.keys.push_back(key);
  }
  return path;
}

}  // namespace treecut::tools
