// What the files of the hierarchical Z-map culler share (hzm_preprocess.cpp,
// hzm_occluders.cpp, hzm_pyramid.cpp, hzm_reference.cpp).
// Peng & Cao, "Integrating Occlusion Culling and Parallel LOD for Rendering
// Complex 3D Environments on GPU", I3D 2013
// (../shared/papers/occlusion-culling-with-parallel-lod.txt), section 6,
// on the CPU cores. What each step does and why it is conservative: hzm.hpp
// and docs/many-objects.md, "Occlusion culling with a hierarchical Z-map".
#pragma once

#include <algorithm>
#include <cstddef>
#include <limits>

#include "treecut/culling/many_objects.hpp"

namespace treecut::culling::detail {

inline constexpr float kInf = std::numeric_limits<float>::infinity();
/// Objects per chunk of the per-object passes.
inline constexpr std::size_t kObjectGrain = 4096;

}  // namespace treecut::culling::detail
