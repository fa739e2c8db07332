// PLY import: our own header/body guard in front of OpenMesh's reader.
//
// OpenMesh alone aborts on absurd counts, silently drops rows of a truncated
// ascii body and accepts garbage tokens, so load_ply() validates the header and
// the body size first, reads through OpenMesh, and checks the counts after.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "treecut/point_set.hpp"

namespace treecut {

struct PlyLoadReport {
  std::size_t vertices_in_file = 0;   ///< as the header declares
  std::size_t dropped_nonfinite = 0;  ///< points with NaN/inf or |x| > 1e18 coordinates, dropped
  std::size_t faces_in_file = 0;      ///< face (or tristrip triangle) count read
  bool had_normals = false;
  bool had_colors = false;
  bool had_radius = false;
  /// A face or tristrips element did not match its header (rows with more or
  /// fewer values than declared, truncated, a list length out of range): it was
  /// ignored with a warning and the points loaded without faces.
  bool faces_lost = false;
};

/// Called with one line per warning (dropped points, ignored elements...).
using WarningSink = std::function<void(const std::string&)>;

/// Loads positions and whatever normals, colors, radii and triangles the file
/// holds. Derives nothing (see attributes.hpp). Throws InputError with one line
/// "PATH: problem" on any malformed input; never allocates more than the file
/// size justifies. Thread-safe; concurrent calls serialize only while inside
/// OpenMesh's reader, which is a process-wide singleton with per-file state.
///
/// What it normalizes, each with a warning through WARN: points with
/// non-finite coordinates, or beyond 1e18 in magnitude (where the float
/// arithmetic of attributes and build overflows), are dropped (with the faces
/// that use them); faces
/// with out-of-range indices or fewer than 3 vertices are dropped; polygons
/// become triangle fans and tristrips become triangles; normals are scaled to
/// unit length (non-finite or zero ones become zero); radii are kept only if
/// all are finite and > 0; colors are opaque (a file alpha is ignored), float
/// colors map [0, 1] to [0, 255] with rounding.
PointSet load_ply(const std::filesystem::path& path, PlyLoadReport* report = nullptr,
                  const WarningSink& warn = {});

/// load_ply() on the bytes of a file already in memory; NAME stands for the
/// path in messages. Accepts arbitrary bytes (fuzzing entry point): anything
/// malformed is an InputError, allocations stay proportional to BYTES.size().
PointSet load_ply_from_memory(std::string_view bytes, const std::string& name,
                              PlyLoadReport* report = nullptr, const WarningSink& warn = {});

/// A PLY file's points in batches (issue 44: a build that holds a batch,
/// not the file). A binary file whose only rows are vertices of fixed size
/// (what scanners and converters write for a cloud) is read a batch of rows
/// at a time: each goes through load_ply()'s guard and reader as a file of
/// those rows alone, positions relative to the first batch's origin. Any
/// other file (ascii, faces, lists, a body not the header's size) is one
/// batch of every point, load_ply() itself. Warnings as load_ply() gives
/// them: about the header once, with the first batch; the totals of what
/// was dropped or cleared once, with the last. Throws as load_ply() does
/// (a file of no usable point: from the call that reads its end).
class PlyReader {
 public:
  /// Opens PATH (held open until destruction).
  explicit PlyReader(const std::filesystem::path& path, const WarningSink& warn = {});
  /// Reads BYTES (which must outlive the reader); NAME stands for the path.
  PlyReader(std::string_view bytes, const std::string& name, const WarningSink& warn = {});
  ~PlyReader();
  PlyReader(PlyReader&&) noexcept;
  PlyReader& operator=(PlyReader&&) noexcept;

  /// The next batch of at most MAX_POINTS points (fewer where some are
  /// dropped, never none before the end); none at the end.
  PointSet next(std::size_t max_points);
  /// Whether the file is read in batches (else next() gives it whole).
  [[nodiscard]] bool streams() const;
  /// What load_ply() reports, of the batches so far.
  [[nodiscard]] const PlyLoadReport& report() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// How save_ply and save_pcd write positions.
struct SaveOptions {
  /// Positions relative to points.frame.origin, as floats, with the origin
  /// in a treecut comment (which treecut's readers add back): for programs
  /// that read no double positions (`export --relative`). Otherwise the
  /// file's coordinates: doubles where the model has an origin.
  bool relative = false;
};

/// Writes binary little-endian PLY that holds everything the points have
/// (issue 43): x y z (doubles of the file's coordinates where the model has
/// an origin, floats otherwise), nx ny nz float, red green blue (uchar, or
/// ushort with colors16) and radius float when present (curvature is not
/// written), every attribute as a property of its name in a type that holds
/// it (typed_values: the file's own, or a double), a face element (list
/// uchar int) when triangles are present, and the coordinate system and GPS
/// time type as treecut comments. Writes through an AtomicFile (a temporary
/// beside PATH, renamed over it when complete), so readers never see a
/// partial file and a failed write (full disk) leaves PATH as it was and no
/// temporary. Throws std::invalid_argument if an attribute array has the
/// wrong size or a triangle index is out of range, std::runtime_error "PATH:
/// REASON" on I/O errors (and when PATH is a directory or a FIFO).
void save_ply(const std::filesystem::path& path, const PointSet& points,
              const SaveOptions& options = {});

/// Whether PATH is a PLY file save_ply wrote, whole: its header line for
/// line and the size its header implies (what `export` and `gen` may
/// replace).
[[nodiscard]] bool is_own_ply(const std::filesystem::path& path);

}  // namespace treecut
