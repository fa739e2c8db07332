// Reading a model's points (model_read.hpp).
#include "model_read.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <string_view>

#include "import/ply_format.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/pcd.hpp"
#include "treecut/text_cloud.hpp"

namespace treecut {

namespace {

// Whether TEXT is comment lines ('#') only, the last perhaps cut off.
bool only_comments(std::string_view text) {
  for (std::size_t at = 0; at < text.size();) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view line = text.substr(at, end - at);
    if (!line.empty() && line.front() != '#' && line != "\r") return false;
    at = end + 1;
  }
  return true;
}

}  // namespace

std::string detail::read_head(const std::filesystem::path& path, std::size_t n) {
  std::ifstream in(path, std::ios::binary);
  std::string head(n, '\0');
  in.read(head.data(), static_cast<std::streamsize>(n));
  head.resize(static_cast<std::size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return head;
}

detail::PointFormat detail::point_format(const std::filesystem::path& model,
                                         const std::vector<std::string>& columns) {
  // The format from the first bytes: 4 KiB, or up to 1 MiB while they are
  // only comment lines (a PCD may open with a long one).
  std::string head = detail::read_head(model, 4096);
  if (head.size() == 4096 && only_comments(head))
    head = detail::read_head(model, std::size_t{1} << 20);
  const bool las = head.starts_with("LASF");
  // A byte order mark before 'ply' is the PLY reader's to name.
  const bool ply = !las && (head.starts_with("ply") || head.starts_with("\xEF\xBB\xBFply"));
  const bool pcd = !las && !ply && looks_like_pcd(head);
  // Text with another format's signature (E57's "ASTM-E57") is named as that.
  const bool text =
      !las && !ply && !pcd && ply::other_format(head).empty() && looks_like_text_cloud(head);
  if (!columns.empty() && !text) {
    throw InputError(quoted_name(model) +
                     ": --columns names the columns of a text cloud (XYZ, PTS, CSV); this file "
                     "names its own fields");
  }
  return las    ? PointFormat::las
         : pcd  ? PointFormat::pcd
         : text ? PointFormat::text
         : ply  ? PointFormat::ply
                : PointFormat::other;
}

// The points of a model file, by its first bytes: LAS ("LASF"), PLY, PCD
// (pcd.hpp) or, for any other text, a text cloud (text_cloud.hpp), whose
// reader comes closest to what such a file is (which column is named twice,
// which line). A binary file that is neither gets the PLY reader's message
// (it names the format it recognizes: E57, an image...) and what treecut
// reads.
PointSet detail::read_point_file(const std::filesystem::path& model, OpenedModel& out,
                                 const WarningSink& warn, const std::vector<std::string>& columns) {
  const PointFormat format = point_format(model, columns);
  const bool las = format == PointFormat::las, pcd = format == PointFormat::pcd,
             text = format == PointFormat::text, ply = format == PointFormat::ply;
  if (las) {
    out.format = "LAS";
    return load_las(model, &out.las, warn);
  }
  if (pcd) {
    out.format = "PCD";
    return load_pcd(model, warn);
  }
  if (text) {
    out.format = "text";
    try {
      return load_text_cloud(model, warn, columns);
    } catch (const InputError& e) {
      // A text with no positions at all may be no point cloud: say what is read.
      const std::string what = e.what();
      if (what.find(": the header names no x, y, z columns") == std::string::npos) throw;
      throw InputError(what + "; treecut reads PLY, LAS, PCD and text (XYZ, PTS, CSV) point files");
    }
  }
  out.format = "PLY";
  if (ply) return load_ply(model, &out.ply, warn);
  try {
    return load_ply(model, &out.ply, warn);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) +
                     "; treecut reads PLY, LAS, PCD and text (XYZ, PTS, CSV) point files");
  }
}

std::vector<std::filesystem::path> point_files_in(const std::filesystem::path& folder) {
  // .laz is listed so that a compressed tile is named and refused, not
  // left out of the cloud without a word.
  static constexpr std::string_view kExtensions[] = {".las", ".laz", ".ply", ".pcd",
                                                     ".xyz", ".pts", ".csv", ".txt"};
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  std::filesystem::directory_iterator it(folder, ec), end;
  if (ec) throw InputError(system_error_text(folder, ec.value()));
  for (; it != end; it.increment(ec)) {
    std::string ext = it->path().extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (std::find(std::begin(kExtensions), std::end(kExtensions), ext) == std::end(kExtensions))
      continue;
    std::error_code type_error;
    if (it->is_regular_file(type_error)) files.push_back(it->path());
  }
  if (ec) throw InputError(system_error_text(folder, ec.value()));
  if (files.empty())
    throw InputError(quoted_name(folder) +
                     ": is a directory without point files (.las, .laz, .ply, .pcd, .xyz, .pts, "
                     ".csv, .txt); a folder is the model of the point files in it");
  std::sort(files.begin(), files.end());
  return files;
}

void detail::check_same_system(const std::filesystem::path& first_file, const PointSet& first,
                               const std::filesystem::path& file, const PointSet& more,
                               const WarningSink& warn) {
  if (more.frame.crs != first.frame.crs) {
    const auto words = [](const std::string& crs) {
      return crs.empty() ? std::string("none") : "\"" + crs + "\"";
    };
    throw InputError(quoted_name(file) + ": its coordinate system (" + words(more.frame.crs) +
                     ") is not that of " + quoted_name(first_file) + " (" + words(first.frame.crs) +
                     "); the files of one model share one");
  }
  if (more.adjusted_gps_time != first.adjusted_gps_time && warn) {
    warn(quoted_name(file) + ": its GPS times are " +
         (more.adjusted_gps_time ? "adjusted standard" : "seconds of the week") +
         " time, those of " + quoted_name(first_file) + " are not");
  }
}

std::string detail::format_text(const OpenedModel& out) {
  const std::string files = out.files > 1 ? "; " + std::to_string(out.files) + " files" : "";
  if (out.format != "LAS") return out.format + files;
  const LasInfo& l = out.las.info;
  std::string text = "LAS " + std::to_string(l.version_major) + "." +
                     std::to_string(l.version_minor) + ", point format " +
                     std::to_string(l.point_format) + " (" + std::to_string(l.record_length) +
                     " bytes a point)";
  if (!l.system_identifier.empty()) text += ", from " + one_line(l.system_identifier);
  return text + files;
}

PointSet detail::read_point_files(
    std::span<const std::filesystem::path> files, OpenedModel& out, const WarningSink& warn,
    const std::vector<std::string>& columns,
    const std::function<void(std::string_view, std::size_t, std::size_t)>& progress) {
  PointSet all;
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (progress) progress("read", i, files.size());
    OpenedModel one;
    PointSet points = read_point_file(files[i], one, warn, columns);
    if (i == 0) {
      out.format = one.format;
      out.ply = one.ply;
      out.las = one.las;
    } else {
      check_same_system(files[0], all, files[i], points, warn);
    }
    out.las.dropped_nonfinite += i == 0 ? 0 : one.las.dropped_nonfinite;
    all.append(std::move(points));
  }
  if (progress) progress("read", files.size(), files.size());
  return all;
}

}  // namespace treecut
