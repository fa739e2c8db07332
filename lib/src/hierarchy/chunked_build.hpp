// A build in bounded memory (issue 44, item 2), after PotreeConverter 2
// (Schütz, Ohrhallinger and Wimmer 2020, "Fast Out-of-Core Octree
// Generation for Massive Point Clouds"): a counting pass over the files, the
// points distributed into chunks on disk (each with a halo of its
// neighbours' points near its border), each chunk's normals, radii and
// curvature from its points and halo, then each chunk built by
// build_hierarchy and written as pages, and the levels over the chunks'
// roots on top (subtree_roots.hpp). Every point's normal, radius and
// curvature are those of a build held whole: its neighbours are its k
// nearest within the model's NeighbourReach (attributes.hpp), which is the
// halo's width, and what only the whole decides (the centroid normals face
// away from, the median that fills and caps the radii) is taken over the
// whole.
// Private to the library (open_model chooses it for a model past its
// memory budget).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>

#include "treecut/model_io.hpp"

namespace treecut::detail {

struct ChunkedBuildReport {
  std::uint64_t points = 0;
  std::size_t chunks = 0;
  unsigned lanes = 1;               ///< chunks built at once
  std::uint64_t largest_chunk = 0;  ///< points, halo included
  std::uint64_t halo_points = 0;    ///< copies of points in other chunks' halos
  float halo = 0.0f;                ///< its width, model units
  std::uint64_t scratch_bytes = 0;  ///< the most temporary disk held at once
  std::uint64_t nodes = 0;          ///< of the hierarchy written
  std::uint32_t value_streams = 0;  ///< attributes stored per node
};

/// The bytes this process holds in memory now (/proc/self/statm's resident
/// pages).
std::uint64_t resident_bytes();

/// Builds the model of FILES in ROOM bytes (beside what the program holds
/// already) into the cache file CACHE
/// (atomically, keyed on KEY), its notes' warnings into NOTES; OUT gets the
/// format, the reader's report, the input points and the stages' seconds.
/// AFTER_READ is called once the files are read for the last time (before
/// anything is written under CACHE's name): it throws to stop the build.
/// Temporary files lie beside CACHE, and go on any exit. Throws InputError
/// for a file that cannot be read (named), std::runtime_error for one that
/// cannot be written.
ChunkedBuildReport build_chunked(std::span<const std::filesystem::path> files,
                                 const OpenOptions& options, const CacheKey& key,
                                 const std::filesystem::path& cache, std::uint64_t room,
                                 const std::function<void()>& after_read, SourceNotes& notes,
                                 OpenedModel& out);

}  // namespace treecut::detail
