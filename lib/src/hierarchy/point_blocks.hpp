// Points on their way through the chunked build (chunked_build.cpp): a
// PointSet's points, or some of them, as one compressed block of columns,
// and back. Every per-point array travels exactly (positions, normals,
// radii, curvature, colours at 8 and 16 bits, each attribute in the form it
// has: floats from an offset, doubles, 64-bit integers or one constant), so
// that a chunk read back is, value for value, what the reader handed out.
// The frame, records and faces stay behind (the build keeps one frame; a
// mesh is never chunked). Private to the library.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::detail {

/// The points of PS at INDICES, in that order, as one zstd frame.
std::vector<unsigned char> pack_points(const PointSet& ps, std::span<const std::uint32_t> indices);

/// A block of pack_points as points (frame left default). Throws
/// std::runtime_error for bytes that are not such a block.
PointSet unpack_points(std::span<const unsigned char> block);

/// The first N points of PS, every per-point array cut to them (N <= size()).
void keep_first(PointSet& ps, std::size_t n);

}  // namespace treecut::detail
