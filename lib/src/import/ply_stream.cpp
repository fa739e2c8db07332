// A PLY file's points in batches (PlyReader, treecut/ply.hpp). A binary
// cloud whose rows are fixed-size vertices is cut into files of a batch of
// rows each, under the file's own header with the vertex count of the
// batch, and every one of them goes through load_ply()'s pipeline (the
// guard, OpenMesh, tidy): the streamed read is the whole read's, a batch
// at a time, and the guard stays the one place that knows OpenMesh.
#include <algorithm>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "byte_source.hpp"
#include "ply_load_parts.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/ply.hpp"

namespace treecut {

struct PlyReader::State {
  State(detail::StreamedFile f, const WarningSink& sink) : file(std::move(f)), warn(sink) {
    open();
  }
  detail::StreamedFile file;
  WarningSink warn;
  PlyLoadReport report;
  // Streamed: the header before and after the vertex count, the rows.
  bool streams = false;
  std::string head, tail;
  std::uint64_t body = 0, rows = 0, next = 0;
  std::size_t stride = 0;
  std::string batch;  // the file of one batch, reused
  std::optional<glm::dvec3> origin;
  std::set<std::string> said;  // the header's warnings, given with the first batch
  ply_load::Tidied tidied;
  std::uint64_t delivered = 0;
  bool done = false;

  void open();
  PointSet whole();
  PointSet read(std::size_t n);
  void finish();
};

// Whether the file streams, and its header around the vertex count.
void PlyReader::State::open() {
  const std::uint64_t size = file.source->size();
  file.parse_head<ply::Error>([&](std::string_view prefix) {
    const ply::Header h = ply::parse_header(prefix);
    const int v = h.find("vertex");
    if (h.format == ply::Format::ascii || v < 0) return;
    const ply::Element& vertex = h.elements[static_cast<std::size_t>(v)];
    const bool vertices_alone =
        std::all_of(h.elements.begin(), h.elements.end(),
                    [&](const ply::Element& e) { return &e == &vertex || e.count == 0; });
    if (!vertices_alone || vertex.has_lists()) return;
    stride = vertex.fixed_stride();
    // A body that is not the header's size is load_ply()'s to name.
    if (stride == 0 || vertex.count > (size - h.body_offset) / stride ||
        h.body_offset + vertex.count * stride != size)
      return;
    head = prefix.substr(0, vertex.count_at);
    tail = prefix.substr(vertex.count_at + vertex.count_size,
                         h.body_offset - vertex.count_at - vertex.count_size);
    body = h.body_offset, rows = vertex.count;
    streams = true;
  });
}

PointSet PlyReader::State::whole() {
  done = true;
  return file.whole([&](const std::filesystem::path& p) { return load_ply(p, &report, warn); },
                    [&](std::string_view bytes, const std::string& name) {
                      return load_ply_from_memory(bytes, name, &report, warn);
                    });
}

// The next N rows through the pipeline.
PointSet PlyReader::State::read(std::size_t n) {
  const std::string count = std::to_string(n);
  batch.resize(head.size() + count.size() + tail.size() + n * stride);
  char* out = batch.data();
  out = std::copy(head.begin(), head.end(), out);
  out = std::copy(count.begin(), count.end(), out);
  out = std::copy(tail.begin(), tail.end(), out);
  file.source->read(body + next * stride, out, n * stride);
  std::vector<std::string> warnings;
  const WarningSink keep = [&](const std::string& w) { warnings.push_back(w); };
  PlyLoadReport one;
  PointSet points =
      ply_load::load_batch(batch, file.name, one, warn ? keep : WarningSink{}, origin, tidied);
  if (next == 0) {
    report = one;
    origin = points.frame.origin;
  }
  next += n;
  report.vertices_in_file = rows;
  report.dropped_nonfinite = tidied.nonfinite + tidied.huge;
  // The header's warnings are every batch's: said once.
  for (std::string& w : warnings)
    if (said.insert(w).second) warn(w);
  return points;
}

// After the last rows: the file's totals, or its error.
void PlyReader::State::finish() {
  done = true;
  if (delivered == 0) throw InputError(file.name + ": " + ply_load::no_usable_points(tidied));
  if (warn) ply_load::say(tidied, ply_load::Warnings(file.name, warn));
}

PlyReader::PlyReader(const std::filesystem::path& path, const WarningSink& warn)
    : state_(std::make_unique<State>(detail::StreamedFile(path), warn)) {}

PlyReader::PlyReader(std::string_view bytes, const std::string& name, const WarningSink& warn)
    : state_(std::make_unique<State>(detail::StreamedFile(bytes, name), warn)) {}

PlyReader::~PlyReader() = default;
PlyReader::PlyReader(PlyReader&&) noexcept = default;
PlyReader& PlyReader::operator=(PlyReader&&) noexcept = default;

bool PlyReader::streams() const {
  return state_->streams;
}

const PlyLoadReport& PlyReader::report() const {
  return state_->report;
}

PointSet PlyReader::next(std::size_t max_points) {
  State& s = *state_;
  if (s.done) return {};
  if (!s.streams) return s.whole();
  while (s.next < s.rows) {
    const auto n = static_cast<std::size_t>(
        std::min<std::uint64_t>(std::max<std::size_t>(max_points, 1), s.rows - s.next));
    PointSet points = s.read(n);
    s.delivered += points.size();
    if (s.next == s.rows) s.finish();
    if (points.size() > 0) return points;
  }
  return {};
}

}  // namespace treecut
