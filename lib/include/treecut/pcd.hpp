// PCD import: the Point Cloud Library's format (PCL "The PCD (Point Cloud
// Data) file format", v0.7; v0.6 and v0.5 headers too), what robotics
// sensors and PCL pipelines write. Its own guarded reader (Debian's PCL
// would bring the whole library for one format).
//
// A header of lines (FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT,
// POINTS, DATA) and the points as DATA says: ascii (a line a point), binary
// (packed records, little-endian) or binary_compressed (LZF, liblzf, of the
// fields one after the other). What is kept: x y z (in double, relative to
// an origin where they need one, as every reader), normal_x/y/z, the colour
// of an `rgb` or `rgba` field (the bytes of a float or an unsigned int, as
// PCL packs them) or of separate red, green and blue fields (8 or 16 bits),
// and every other scalar field as a named attribute in its own type
// (intensity, label, curvature, ...); field names are matched without
// regard to case (X Y Z, as PDAL writes them). Fields with a COUNT above 1
// (descriptors such as fpfh) and `_` padding are named in one warning.
// Points whose position is NaN (an organized cloud's holes) are dropped,
// counted in a warning. The VIEWPOINT of an organized cloud (a depth
// camera's), or any that is not the identity, is the sensor's pose
// (CoordinateFrame::viewpoint): the first view opens from it.
//
// Guarded as the other readers: every header line checked (known types and
// sizes, counts that agree, WIDTH x HEIGHT = POINTS), the data's bytes
// checked against the file before anything is sized, a compressed block's
// sizes against its LZF bound; a malformed file is one InputError
// "NAME: problem" (exit 2).
#pragma once

#include <filesystem>
#include <memory>
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

/// A PCD file's points in batches (issue 44: a build that holds a batch,
/// not the file). A binary body is read a batch of records at a time,
/// positions relative to the first batch's origin; an ascii or
/// binary_compressed one (LZF over each field of every point), or one with
/// float colour channels (scaled by the file's brightest), is one batch of
/// the whole read, load_pcd() itself. Warnings as load_pcd() gives them,
/// with the last batch. Throws as load_pcd() does (a file of no usable
/// point: from the call that reads its end).
class PcdReader {
 public:
  /// Opens PATH (held open until destruction).
  explicit PcdReader(const std::filesystem::path& path, const WarningSink& warn = {});
  /// Reads BYTES (which must outlive the reader); NAME stands for the path.
  PcdReader(std::string_view bytes, const std::string& name, const WarningSink& warn = {});
  ~PcdReader();
  PcdReader(PcdReader&&) noexcept;
  PcdReader& operator=(PcdReader&&) noexcept;

  /// The next batch of at most MAX_POINTS points (fewer where some are
  /// dropped, never none before the end); none at the end.
  PointSet next(std::size_t max_points);
  /// Whether the file is read in batches (else next() gives it whole).
  [[nodiscard]] bool streams() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

enum class PcdData { ascii, binary, binary_compressed };

/// The first line save_pcd writes: how is_own_pcd knows treecut's files.
inline constexpr std::string_view kPcdSignature =
    "# .PCD v0.7 - Point Cloud Data file format (treecut)\n";

/// Writes a PCD v0.7 file: x y z (doubles of the file's coordinates where
/// the model has an origin, floats otherwise; relative floats with
/// OPTIONS.relative), normal_x/y/z, the colour (a packed rgb, or red green
/// blue of 16 bits with colors16) and every attribute as a field of its
/// name in a type that holds it, the coordinate system and GPS time type
/// as treecut comments. Through an AtomicFile like save_ply; throws
/// std::invalid_argument for inconsistent sizes, std::runtime_error "PATH:
/// REASON" on I/O errors. What `gen -o X.pcd`, `export` and the tests
/// write.
void save_pcd(const std::filesystem::path& path, const PointSet& points,
              PcdData data = PcdData::binary_compressed, const SaveOptions& options = {});

/// Whether PATH is a PCD file save_pcd wrote, whole: its first line, a
/// header that parses and a binary or compressed body of the size the
/// header says (what `export` and `gen` may replace; they write no ascii).
[[nodiscard]] bool is_own_pcd(const std::filesystem::path& path);

}  // namespace treecut
