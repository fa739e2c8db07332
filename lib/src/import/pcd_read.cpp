// PCD import (treecut/pcd.hpp): after the header (pcd_header.cpp), the
// points of an ascii, binary or binary_compressed body (pcd_records.cpp),
// whole or, binary, in batches (PcdReader).
#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "attribute_column.hpp"
#include "byte_source.hpp"
#include "file_metadata.hpp"
#include "pcd_header.hpp"
#include "pcd_records.hpp"
#include "position_frame.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/pcd.hpp"
#include "whole_file.hpp"

namespace treecut {

using namespace pcd;

namespace {

// The body's size checked against the header before anything is sized
// from POINTS (the Builder reserves for every point).
void check_size(const Header& h, std::uint64_t left) {
  if (h.data == Data::ascii) {
    // Each value needs a character and a separator.
    std::uint64_t per_line = 0;
    for (const Field& f : h.fields) per_line += f.count;
    if (h.points * per_line > left) {
      throw PcdError(std::to_string(h.points) + " points of " + std::to_string(per_line) +
                     " values cannot fit in the " + std::to_string(left) +
                     " bytes after the header");
    }
  } else if (h.data == Data::binary && h.points * h.record > left) {
    throw PcdError(std::to_string(h.points) + " points of " + std::to_string(h.record) +
                   " bytes declared, the data holds " + std::to_string(left / h.record));
  }
}

// The points B took from the body of a file with header H: colours,
// attributes, positions relative to ORIGIN (chosen from them when none;
// what place_points drops added to DROPPED), the pose, treecut's metadata.
PointSet points_of(const Header& h, Builder& b, const std::optional<glm::dvec3>& origin,
                   detail::Dropped& dropped) {
  b.colours_from_channels();
  PointSet points = std::move(b.points);
  detail::take_columns(b.attributes, points.attributes);
  dropped = detail::place_points(std::move(b.doubles), points, origin);
  std::vector<glm::dvec3>().swap(b.doubles);
  set_viewpoint(h, points);
  for (const std::string& comment : h.comments) detail::read_metadata_line(comment, points);
  return points;
}

// The checks and warnings of a file once its last point is read: none
// usable, the points dropped, the fields not kept.
void finish(std::size_t kept, const detail::Dropped& dropped, const Roles& r,
            const WarningSink& warn) {
  if (kept == 0) {
    throw PcdError(dropped.far > 0
                       ? "no usable points (" + dropped.far_message(dropped.first_far + 1) + ")"
                       : "no points with a finite position");
  }
  if (!warn) return;
  if (dropped.nonfinite > 0) {
    warn("dropped " + std::to_string(dropped.nonfinite) + " points without a finite position");
  }
  if (dropped.far > 0) warn(dropped.far_message(dropped.first_far + 1));
  if (!r.not_kept.empty()) warn("fields not kept: " + detail::join_some(r.not_kept));
}

PointSet parse(std::string_view file, const WarningSink& warn) {
  const Header h = parse_header(file);
  const Roles r = roles_of(h);
  const std::uint64_t left = file.size() - h.body;
  const auto* body = reinterpret_cast<const unsigned char*>(file.data()) + h.body;
  check_size(h, left);
  std::vector<unsigned char> columns;
  if (h.data == Data::compressed) columns = unpack(body, left, h, h.points * h.record);
  Builder b(h, r);
  if (h.data == Data::ascii) {
    read_ascii(file, h, b);
  } else if (h.data == Data::binary) {
    read_packed(body, h, b);
  } else {
    read_columns(columns.data(), h, b);
    std::vector<unsigned char>().swap(columns);
  }
  detail::Dropped dropped;
  PointSet points = points_of(h, b, std::nullopt, dropped);
  finish(points.size(), dropped, r, warn);
  return points;
}

}  // namespace

PointSet load_pcd_from_memory(std::string_view bytes, const std::string& name,
                              const WarningSink& warn) {
  try {
    const WarningSink named = [&](const std::string& w) {
      if (warn) warn(name + ": " + w);
    };
    return parse(bytes, warn ? named : WarningSink{});
  } catch (const PcdError& e) {
    throw InputError(name + ": " + e.what());
  }
}

PointSet load_pcd(const std::filesystem::path& path, const WarningSink& warn) {
  const detail::WholeFile file = detail::read_whole_file(path);
  return load_pcd_from_memory(file.bytes(), quoted_name(path), warn);
}

// A PCD file being read in batches: its header, and what the batches so
// far found (the origin the first chose, the points dropped).
struct PcdReader::State {
  State(detail::StreamedFile f, const WarningSink& sink) : file(std::move(f)), warn(sink) {
    open();
  }
  detail::StreamedFile file;
  WarningSink warn;
  bool streams = false, done = false;
  Header h;
  Roles r;
  std::uint64_t next = 0, read = 0, kept = 0;
  std::vector<unsigned char> rows;  // a batch's records, reused
  std::optional<glm::dvec3> origin;
  detail::Dropped dropped;

  // Whether the file streams: binary records, as many as the header says,
  // and no colour scaled by the file's brightest value (float channels).
  void open() {
    const std::uint64_t size = file.source->size();
    file.parse_head<PcdError>([&](std::string_view prefix) {
      h = parse_header(prefix);
      r = roles_of(h);
      const bool float_channels =
          r.channel[0] >= 0 && h.fields[static_cast<std::size_t>(r.channel[0])].type == 'F';
      streams = h.data == Data::binary && h.record > 0 && h.points > 0 && !float_channels &&
                h.points <= (size - h.body) / h.record;
    });
  }

  PointSet whole() {
    done = true;
    return file.whole([&](const std::filesystem::path& p) { return load_pcd(p, warn); },
                      [&](std::string_view bytes, const std::string& name) {
                        return load_pcd_from_memory(bytes, name, warn);
                      });
  }

  // The next N records.
  PointSet batch(std::size_t n) {
    rows.resize(n * h.record);
    file.source->read(h.body + next * h.record, rows.data(), rows.size());
    Header part = h;
    part.points = n;
    Builder b(part, r);
    read_packed(rows.data(), part, b);
    detail::Dropped d;
    PointSet points = points_of(h, b, origin, d);
    dropped.add(d, read);
    read += n, next += n;
    // The origin is the first batch's with a point in it.
    if (!origin && points.size() > 0) origin = points.frame.origin;
    kept += points.size();
    return points;
  }
};

PcdReader::PcdReader(const std::filesystem::path& path, const WarningSink& warn)
    : state_(std::make_unique<State>(detail::StreamedFile(path), warn)) {}

PcdReader::PcdReader(std::string_view bytes, const std::string& name, const WarningSink& warn)
    : state_(std::make_unique<State>(detail::StreamedFile(bytes, name), warn)) {}

PcdReader::~PcdReader() = default;
PcdReader::PcdReader(PcdReader&&) noexcept = default;
PcdReader& PcdReader::operator=(PcdReader&&) noexcept = default;

bool PcdReader::streams() const {
  return state_->streams;
}

PointSet PcdReader::next(std::size_t max_points) {
  State& s = *state_;
  if (s.done) return {};
  if (!s.streams) return s.whole();
  try {
    while (s.next < s.h.points) {
      const auto n = static_cast<std::size_t>(
          std::min<std::uint64_t>(std::max<std::size_t>(max_points, 1), s.h.points - s.next));
      PointSet points = s.batch(n);
      if (s.next == s.h.points) {
        s.done = true;
        const WarningSink named = [&](const std::string& w) { s.warn(s.file.name + ": " + w); };
        finish(s.kept, s.dropped, s.r, s.warn ? named : WarningSink{});
      }
      if (points.size() > 0) return points;
    }
  } catch (const PcdError& e) {
    throw InputError(s.file.name + ": " + e.what());
  }
  return {};
}

}  // namespace treecut
