// Text point clouds: what scanning software exports as XYZ, PTS or CSV.
//
// - XYZ: one point a line, numbers separated by spaces, tabs, commas or
//   semicolons: x y z, then optionally r g b (0-255 integers) and the rest.
// - PTS (Leica): a first line with the point count alone, then x y z
//   intensity r g b lines.
// - CSV with a header line naming the columns: x, y, z (also X, //X, east,
//   north, height...), red, green, blue (or r, g, b), nx, ny, nz; every
//   other column is an attribute of its name, `_` a column skipped. A
//   mapping given by the caller (`--columns x,y,z,intensity,_`) names the
//   columns of a file without a header, or instead of its header.
// Without a header the columns say what they are: 3 (x y z), 4 (x y z and a
// scalar), 6 (x y z r g b when the last three are whole numbers from 0 to
// 255, else x y z nx ny nz), 7 (PTS's x y z intensity r g b). Lines end at
// LF, CR LF or a lone CR; a byte order mark is skipped; "nan" is no value
// (a point without a finite position is dropped and counted).
//
// Positions are read in double and kept relative to an origin where they
// need one, by the rule every reader follows (PointSet::frame). Guarded as the other readers: a
// line that does not parse, a column count that changes, a PTS count that
// disagrees with the lines, a colour out of 0-255 is one InputError
// "NAME:LINE: problem" (exit 2); nothing is sized from a count before the
// lines are there.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/ply.hpp"  // WarningSink
#include "treecut/point_set.hpp"

namespace treecut {

/// Whether BYTES (a file's first bytes) are text (printable ASCII or UTF-8,
/// tabs and line ends, a byte order mark first): what the text reader takes
/// when no other format's signature is there, so that a text that is no
/// point cloud gets its message (the header names x twice, line 7 has 4
/// values), not another reader's.
[[nodiscard]] bool looks_like_text_cloud(std::string_view bytes);

/// Loads a text cloud (see above). COLUMNS, when given, names every column
/// in order as a header would (x, y, z, r/red, g, b, nx, ny, nz, any other
/// name an attribute, `_` a column skipped) and replaces the file's header
/// line if it has one (`--columns`). Throws InputError "NAME:LINE: problem".
PointSet load_text_cloud(const std::filesystem::path& path, const WarningSink& warn = {},
                         const std::vector<std::string>& columns = {});

/// A text cloud's points in batches, the file read a few MiB at a time
/// (the chunked build's reader, issue 44): positions relative to the origin
/// the first batch with a point chose (PointSet::frame); the batch that
/// reaches the last line makes the file's checks (the PTS count, no point
/// at all) and says its warnings. load_text_cloud() is one batch of every
/// point. Throws InputError as load_text_cloud() does, from the
/// constructor (the header, the columns) or from next() (a line).
class TextCloudReader {
 public:
  TextCloudReader(const std::filesystem::path& path, const WarningSink& warn = {},
                  const std::vector<std::string>& columns = {});
  /// Reads BYTES (which must outlive the reader); NAME stands for the path.
  TextCloudReader(std::string_view bytes, const std::string& name, const WarningSink& warn = {},
                  const std::vector<std::string>& columns = {});
  ~TextCloudReader();
  TextCloudReader(TextCloudReader&&) noexcept;
  TextCloudReader& operator=(TextCloudReader&&) noexcept;

  /// The next batch of at most MAX_POINTS points read (fewer where some
  /// are dropped, never none before the end); none at the end.
  PointSet next(std::size_t max_points);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// load_text_cloud() on bytes in memory; NAME stands for the path.
PointSet load_text_cloud_from_memory(std::string_view bytes, const std::string& name,
                                     const WarningSink& warn = {},
                                     const std::vector<std::string>& columns = {});

}  // namespace treecut
