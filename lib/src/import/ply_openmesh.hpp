// The OpenMesh stage of PLY import: hands a header we wrote ourselves plus
// already validated body bytes to OpenMesh's PLY reader, with an importer that
// stores straight into PointSet arrays (no halfedge mesh).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::ply {

struct OpenMeshInput {
  /// A complete header ("ply" ... "end_header\n") declaring exactly the
  /// elements in BODY, at most "vertex" then "face", in that order.
  std::string header;
  /// The body, as consecutive pieces (not copied; must outlive the call).
  std::vector<std::string_view> body;
  std::size_t vertices = 0;  ///< rows of "vertex" in the body
  std::size_t faces = 0;     ///< rows of "face" in the body (0 if absent)
  bool normals = false;      ///< the header names nx ny nz
  bool colors = false;       ///< the header names uchar red green blue
};

struct OpenMeshResult {
  bool reader_ok = false;              ///< OpenMesh's own verdict
  std::size_t vertices_read = 0;       ///< add_vertex calls
  std::size_t faces_read = 0;          ///< add_face calls
  std::size_t faces_out_of_range = 0;  ///< faces with an index outside [0, vertices)
  std::size_t faces_degenerate = 0;    ///< faces with fewer than 3 vertices
};

/// Fills positions (and normals, colors if requested) with INPUT.vertices
/// entries and appends the faces as triangles (polygons become fans). Faces
/// with bad indices are counted, not stored. Calls are serialized on a mutex:
/// OpenMesh's reader is a singleton with mutable per-file state.
OpenMeshResult read_with_openmesh(const OpenMeshInput& input, PointSet& points);

}  // namespace treecut::ply
