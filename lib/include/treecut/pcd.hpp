// PCD import: the Point Cloud Library's format (PCL "The PCD (Point Cloud
// Data) file format", v0.7; v0.6 and v0.5 headers too), what robotics
// sensors and PCL pipelines write. Its own guarded reader (Debian's PCL
// would bring the whole library for one format).
//
// A header of lines (FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT,
// POINTS, DATA) and the points as DATA says: ascii (a line a point), binary
// (packed records, little-endian) or binary_compressed (LZF, liblzf, of the
// fields one after the other). What is kept: x y z (in double, relative to
// an origin near the first point, as LAS's), normal_x/y/z, the colour of an
// `rgb` or `rgba` field (the bytes of a float or an unsigned int, as PCL
// packs them), and every other scalar field as a named attribute
// (intensity, label, curvature, ...). Fields with a COUNT above 1
// (descriptors such as fpfh) and `_` padding are named in one warning.
// Points whose position is NaN (an organized cloud's holes) are dropped,
// counted in a warning. The VIEWPOINT is not used.
//
// Guarded as the other readers: every header line checked (known types and
// sizes, counts that agree, WIDTH x HEIGHT = POINTS), the data's bytes
// checked against the file before anything is sized, a compressed block's
// sizes against its LZF bound; a malformed file is one InputError
// "NAME: problem" (exit 2).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "treecut/ply.hpp"  // WarningSink
#include "treecut/point_set.hpp"

namespace treecut {

/// Whether BYTES (a file's first bytes) look like a PCD file: after comment
/// lines, a VERSION or FIELDS line.
[[nodiscard]] bool looks_like_pcd(std::string_view bytes);

/// Loads a PCD file (see above). Throws InputError "NAME: problem".
PointSet load_pcd(const std::filesystem::path& path, const WarningSink& warn = {});

/// load_pcd() on bytes in memory; NAME stands for the path.
PointSet load_pcd_from_memory(std::string_view bytes, const std::string& name,
                              const WarningSink& warn = {});

enum class PcdData { ascii, binary, binary_compressed };

/// Writes a PCD v0.7 file: x y z as floats relative to points.frame.origin
/// (PCD has no offset: the origin is lost, as in PCL), normal_x/y/z and rgb
/// (packed) when the points have them, every attribute as a float field of
/// its name (its offset added). Through an AtomicFile like save_ply; throws
/// std::invalid_argument for inconsistent sizes, std::runtime_error "PATH:
/// REASON" on I/O errors. What `gen -o X.pcd` and the tests write.
void save_pcd(const std::filesystem::path& path, const PointSet& points,
              PcdData data = PcdData::binary_compressed);

}  // namespace treecut
