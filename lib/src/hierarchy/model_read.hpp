// Reading a model's points for open_model (model_io.cpp): one file by its
// first bytes, or the files of one cloud (a folder of tiles, issue 44)
// joined into one PointSet.
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "treecut/model_io.hpp"

namespace treecut::detail {

/// The first N bytes of PATH (fewer if it is shorter; none if it cannot be
/// read).
std::string read_head(const std::filesystem::path& path, std::size_t n);

/// The points of MODEL by its first bytes (LAS, PLY, PCD or a text cloud);
/// OUT gets the format and the reader's report.
/// What a model file is, by its first bytes (LAS: "LASF"; PLY; PCD; any
/// other text a text cloud; other: the PLY reader names what it is).
/// COLUMNS (`--columns`) for a file that is no text cloud: InputError.
enum class PointFormat { las, ply, pcd, text, other };
PointFormat point_format(const std::filesystem::path& model,
                         const std::vector<std::string>& columns);

PointSet read_point_file(const std::filesystem::path& model, OpenedModel& out,
                         const WarningSink& warn, const std::vector<std::string>& columns);

/// Checks that MORE (of FILE) is in the coordinate system of FIRST (of
/// FIRST_FILE): an InputError naming both when it is not; a warning when
/// their GPS time types differ.
void check_same_system(const std::filesystem::path& first_file, const PointSet& first,
                       const std::filesystem::path& file, const PointSet& more,
                       const WarningSink& warn);

/// The file's format as `info` words it (SourceNotes::format): "LAS 1.4,
/// point format 6 (30 bytes a point), from ...; 12 files".
std::string format_text(const OpenedModel& out);

/// The points of FILES in order as one cloud (PointSet::append), each read
/// as read_point_file does; OUT gets the first file's format and report.
/// A file whose coordinate system differs from the first's is an InputError
/// naming both. PROGRESS (may be empty) gets ("read", files done, files).
PointSet read_point_files(
    std::span<const std::filesystem::path> files, OpenedModel& out, const WarningSink& warn,
    const std::vector<std::string>& columns,
    const std::function<void(std::string_view, std::size_t, std::size_t)>& progress);

}  // namespace treecut::detail
