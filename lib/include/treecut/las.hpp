// LAS import and export: the ASPRS LAS format, versions 1.0 to 1.4 (R15),
// point data record formats 0 to 10, read by the project's own guarded
// reader (Debian 12 packages no LAS library). LAZ (the compressed form) is
// recognized and refused with the way out.
//
// What the reader keeps: positions (the integers times the scale plus the
// offset, in double, stored relative to PointSet::origin so that floats keep
// millimetres at map coordinates), RGB (formats 2, 3, 5, 7, 8, 10) and every
// other per-point field as a named attribute (PointSet::attributes):
// intensity, return_number, number_of_returns, classification,
// classification_flags (synthetic 1, key-point 2, withheld 4, overlap 8),
// scanner_channel, scan_direction, edge_of_flight_line, scan_angle
// (degrees), user_data, point_source_id,
// gps_time, nir and the extra bytes by their names. An attribute with one
// value for every point is named in a warning instead of kept. What it
// reports (LasInfo): the header, the coordinate system (the WKT or the
// GeoTIFF keys of the VLRs and EVLRs) and the extra bytes' descriptors.
//
// Guarded as the PLY reader: every count and offset is checked against the
// file size before anything is sized from it; a malformed file is one
// InputError "NAME: problem"; the points are read in chunks, so the memory
// is the PointSet's and a chunk's, never the file's.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/ply.hpp"  // WarningSink
#include "treecut/point_set.hpp"

namespace treecut {

/// One field of the extra bytes after the standard point record, as its
/// descriptor (LAS 1.4 R15, section 2.5.13) says.
struct LasExtraBytes {
  std::string name;
  /// 1-10: uchar .. double; 11-30: arrays of 2 or 3 of them (deprecated in
  /// 1.4, still written); 0: `options` undocumented bytes.
  std::uint8_t data_type = 0;
  std::uint8_t options = 0;  ///< bit 0 no_data, 3 scale, 4 offset are used
  /// Of each element (one, or an array's two or three).
  double no_data[3] = {0, 0, 0}, scale[3] = {1, 1, 1}, offset[3] = {0, 0, 0};
};

/// What a LAS file's header and records say.
struct LasInfo {
  int version_major = 1, version_minor = 2;
  int point_format = 0;
  std::uint32_t record_length = 0;  ///< bytes per point record (>= the format's)
  std::uint64_t point_count = 0;    ///< the points declared (the extended count in 1.4)
  double scale[3] = {0.01, 0.01, 0.01};
  double offset[3] = {0, 0, 0};
  double min[3] = {0, 0, 0};  ///< the header's bounds (file coordinates)
  double max[3] = {0, 0, 0};
  std::string system_identifier, generating_software;
  std::uint16_t file_source_id = 0;
  std::uint16_t global_encoding = 0;  ///< bit 0: adjusted standard GPS time; bit 4: WKT
  /// The coordinate system in words: "WKT: ..." (OGC WKT record), else from
  /// the GeoTIFF keys "EPSG:26915 (projected)" (the projected key wins over
  /// the geographic one, which names only its datum), "EPSG:4326
  /// (geographic)", "user-defined (projected)" (code 32767), or "GeoTIFF: N
  /// keys"; empty if none.
  std::string crs;
  CrsRecords crs_records;  ///< the records themselves, as the file holds them
  /// The other VLRs and EVLRs, kept for an export (not those that describe
  /// this file's encoding: extra bytes, waveform packets, LASzip, COPC).
  std::vector<FileRecord> records;
  std::vector<LasExtraBytes> extra_bytes;  ///< the extra-bytes fields, in record order
  bool waveform = false;                   ///< the format carries wave packets (not read)
};

struct LasLoadReport {
  LasInfo info;
  std::size_t dropped_nonfinite = 0;  ///< points beyond kMaxCoordinate, dropped
};

/// A LAS file's points in batches (issue 44: a build that holds a batch,
/// not the file). The header, VLRs and EVLRs are parsed and checked when it
/// opens, the origin fixed from them and the first point (as load_las
/// does), so every batch has the same frame: its positions relative to one
/// origin, the file's grid, coordinate system and records. load_las() is
/// one batch of every point. Throws as load_las() does, when it opens and
/// from next().
class LasReader {
 public:
  /// Opens PATH (held open until destruction).
  explicit LasReader(const std::filesystem::path& path, const WarningSink& warn = {});
  /// Reads BYTES (which must outlive the reader); NAME stands for the path.
  LasReader(std::string_view bytes, const std::string& name, const WarningSink& warn = {});
  ~LasReader();
  LasReader(LasReader&&) noexcept;
  LasReader& operator=(LasReader&&) noexcept;

  [[nodiscard]] const LasInfo& info() const;
  /// Points not handed out yet.
  [[nodiscard]] std::uint64_t remaining() const;
  /// The next min(MAX_POINTS, remaining()) points (none at the end): their
  /// positions, colours and fields as attributes (each batch keeps a field
  /// with one value in it once). What cannot be kept is said once, by the
  /// first batch; 64-bit integers a double rounded, by the last. Colours
  /// are the file's 16 bits when a channel past 255 is in any of 1,024
  /// records spread over the file (the last one included, looked at by the
  /// first batch) or in any batch so far; else 8-bit values in the 16-bit
  /// fields.
  /// POSITIONS_ONLY: their positions alone, in the same frame (no
  /// colours, fields or exact positions: what a counting pass needs, the
  /// records parsed for three of their fields).
  PointSet next(std::size_t max_points, bool positions_only = false);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// True when BYTES start as a LAS or LAZ file does ("LASF").
[[nodiscard]] bool looks_like_las(std::string_view bytes);

/// Loads a LAS file (see above). Throws InputError "NAME: problem" for a
/// malformed file or a LAZ file, FileChangedError when it changes size while
/// being read.
PointSet load_las(const std::filesystem::path& path, LasLoadReport* report = nullptr,
                  const WarningSink& warn = {});

/// load_las() on bytes in memory; NAME stands for the path in messages. The
/// fuzzing entry point: anything malformed is an InputError.
PointSet load_las_from_memory(std::string_view bytes, const std::string& name,
                              LasLoadReport* report = nullptr, const WarningSink& warn = {});

struct LasWriteOptions {
  /// The coordinates' resolution (file units per integer step): a round
  /// trip is exact to it. 0: the file's own (frame.resolution, a LAS
  /// scale), else the finest power of ten the float positions resolve.
  double scale = 0.0;
};

/// Writes LAS in the smallest point format that holds every field of every
/// point (issue 43): LAS 1.2 formats 0-3 (GPS time 1, RGB 2), or LAS 1.4
/// formats 6-8 when a field needs them (a scanner channel or NIR, classes
/// past 31, returns past 7, the overlap flag, scan angles that are not whole
/// degrees). The standard fields come from the attributes of those names
/// (return 1 of 1 and class 1 without them), every other attribute is an
/// extra-bytes field of its own type, scale and offset; RGB at 16 bits
/// (colors16, else 8 bits x 257); the coordinate system's records as VLRs;
/// the GPS time type in the global encoding. Positions origin +
/// positions[i] as integers of the scale around an offset near the points.
/// Through an AtomicFile like save_ply. Throws std::invalid_argument for a
/// bad scale or sizes, InputError "PATH: ..." for coordinates the scale
/// cannot hold in 32 bits; std::runtime_error "PATH: REASON" on I/O errors.
void save_las(const std::filesystem::path& path, const PointSet& points,
              const LasWriteOptions& options = {});

/// Whether PATH is a LAS file treecut wrote whose whole header checks out:
/// treecut's generating software, a header a LAS reader accepts and a size
/// that is exactly its records' (what `export` and `gen` may replace).
[[nodiscard]] bool is_own_las(const std::filesystem::path& path);

}  // namespace treecut
