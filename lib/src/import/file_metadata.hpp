// What a file says beyond its points that an export must write back
// (issue 43, items 2 and 3): the coordinate system's records, the meaning
// of GPS times, and the coordinate system in words. LAS holds them in its
// header and VLRs; PLY and PCD have no place for them, so treecut writes
// them as comments (`comment treecut crs-wkt 50524f4a...` in PLY, `#
// treecut ...` in PCD) and reads its own comments back: a round trip LAS ->
// PLY -> LAS keeps them. Other programs skip the comments.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::detail {

/// The lines (without "comment " or "# ") that carry POINTS' metadata:
/// "treecut crs-wkt HEX", "treecut geo-keys HEX", "treecut geo-doubles
/// HEX", "treecut geo-ascii HEX", "treecut gps-time adjusted-standard", and
/// with RELATIVE (positions written relative to the origin) "treecut origin
/// X Y Z".
std::vector<std::string> metadata_lines(const PointSet& points, bool relative = false);

/// The line that gives an attribute written as WRITTEN (a format's field
/// names take no spaces, nor a role's name) its name ORIGINAL back:
/// "treecut name WRITTEN HEX".
std::string name_line(const std::string& written, const std::string& original);

/// Reads one comment's text into POINTS when it is such a line (true);
/// anything else is left alone (false). Malformed hex is not metadata. An
/// origin line adds to frame.origin: call it after the positions are read.
bool read_metadata_line(std::string_view text, PointSet& points);

/// The coordinate system in words from its records: the WKT ("WKT: ...",
/// cut to 400 bytes) wins over the GeoTIFF keys, whose projected key
/// (3072) wins over the geographic one (2048), which names only the datum
/// of a projected system; 32767 is user-defined ("EPSG:26915
/// (projected)", "EPSG:4326 (geographic)", "user-defined (projected)").
std::string crs_text(const CrsRecords& records);

/// Whether the records say the coordinates are geographic (longitude and
/// latitude in degrees): the GeoTIFF model type or key, or a WKT that is a
/// GEOGCS / GEOGCRS at its top.
bool crs_is_geographic(const CrsRecords& records);

}  // namespace treecut::detail
