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

/// body(begin, end, chunk) over the chunks of [0, n): on the pool, or on the
/// calling thread when there is none.
template <class Body>
void for_chunks(WorkerPool* pool, std::size_t n, std::size_t grain, Body&& body) {
  if (pool != nullptr) {
    pool->run(n, grain, body);
  } else {
    const std::size_t chunks = WorkerPool::chunk_count(n, grain);
    for (std::size_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain), c);
  }
}

}  // namespace treecut::culling::detail
