// What the chunked build (chunked_build.cpp) reads and learns of the
// whole model on its way: each file in batches, moved to the model's frame
// as a build held whole moves it (PointSet::append), the figures only the
// whole has (bounds, centroid, each field's range and whether it varies),
// and each chunk's fields in the model's forms. Private to the library.
#pragma once

#include <condition_variable>
#include <exception>
#include <filesystem>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "model_read.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/text_cloud.hpp"

namespace treecut::detail {

// A file's points in batches, from its format's reader (a PLY or PCD
// file's records a batch at a time where it is binary and can be cut:
// PlyReader, PcdReader; else the whole file as one batch).
class Batches {
 public:
  Batches(const std::filesystem::path& file, const WarningSink& warn,
          const std::vector<std::string>& columns)
      : file_(file), warn_(warn), columns_(columns) {
    const PointFormat format = point_format(file, columns);
    if (format == PointFormat::las) las_.emplace(file, warn);
    if (format == PointFormat::text) text_.emplace(file, warn, columns);
    if (format == PointFormat::ply) ply_.emplace(file, warn);
    if (format == PointFormat::pcd) pcd_.emplace(file, warn);
  }
  /// The next batch of at most MAX points; none at the end. POSITIONS_ONLY:
  /// a LAS file's positions alone (other formats give all they have).
  PointSet next(std::size_t max, OpenedModel& out, bool positions_only = false);

 private:
  std::filesystem::path file_;
  WarningSink warn_;
  const std::vector<std::string>& columns_;
  std::optional<LasReader> las_;
  std::optional<TextCloudReader> text_;
  std::optional<PlyReader> ply_;
  std::optional<PcdReader> pcd_;
  bool done_ = false;
};

// What the whole model is, gathered as the batches go by, in the order a
// build held whole reads them.
struct Whole {
  PointSet first;  // the first batch's frame, records (no points)
  bool started = false;
  std::uint64_t points = 0;
  glm::vec3 lo{INFINITY}, hi{-INFINITY};
  glm::dvec3 sum{0.0};  // of the float positions, for the centroid
  // Arrays every file has (one without them: computed for all, as append does).
  bool normals = true, radii = true, curvature = true;
  struct Field {
    std::string name;
    AttributeKind kind = AttributeKind::measure;
    double lo = INFINITY, hi = -INFINITY;
    bool seen = false, varies = false;
    double first = 0.0;
    void add(double v) {
      if (!std::isnan(v)) lo = std::min(lo, v), hi = std::max(hi, v);
      if (!seen) {
        seen = true, first = v;
      } else if (!varies) {
        varies = !(v == first || (std::isnan(v) && std::isnan(first)));
      }
    }
  };
  std::vector<Field> fields;
};

/// Moves a batch of FILE to the model's frame (the first file's origin, as
/// PointSet::append moves it) and checks it belongs to the model (its
/// coordinate system: InputError naming both files).
void join_frame(PointSet& batch, const std::filesystem::path& file,
                const std::filesystem::path& first_file, Whole& whole, const WarningSink& warn);

/// The running figures of WHOLE from one batch (in the model's frame).
void gather(const PointSet& batch, Whole& whole);

/// The batches of FILES in order, read one ahead on a thread of its own:
/// decoding a file (a third of the chunked build's read stage on a survey)
/// goes on while the caller sends the batch before to its chunks. At most
/// two batches are held, the caller's and the one being read. The reader's
/// warnings reach WARN on the caller's thread, before the batch they came
/// with; its error is rethrown by next().
class BatchesAhead {
 public:
  BatchesAhead(std::span<const std::filesystem::path> files, std::size_t batch_points,
               const WarningSink& warn, const std::vector<std::string>& columns,
               bool positions_only = false);
  ~BatchesAhead();  // stops the reader after its batch
  BatchesAhead(const BatchesAhead&) = delete;
  BatchesAhead& operator=(const BatchesAhead&) = delete;

  /// The next batch (empty at the end) and the index of its file.
  std::pair<PointSet, std::size_t> next();
  /// After the end: the first file's format and report (as Batches gives
  /// it), with the points every file dropped.
  [[nodiscard]] const OpenedModel& model() const { return model_; }

 private:
  void read(std::span<const std::filesystem::path> files, std::size_t batch_points,
            const std::vector<std::string>& columns, bool positions_only);

  WarningSink warn_;
  OpenedModel model_;  // the reader's until the end
  std::mutex mutex_;
  std::condition_variable changed_;
  // The slot between the threads, guarded by mutex_: a batch, its file,
  // the warnings before it; `end` after the last, `error` instead of one.
  struct Slot {
    bool full = false, end = false, stop = false;
    PointSet batch;
    std::size_t file = 0;
    std::vector<std::string> warnings;
    std::exception_ptr error;
  } slot_;
  std::thread reader_;
};

/// Calls FN(batch, file index) for every batch of every file, in order
/// (read ahead: BatchesAhead); OUT gets the first file's format and report.
/// POSITIONS_ONLY: as Batches::next.
template <class Fn>
void for_each_batch(std::span<const std::filesystem::path> files, std::size_t batch_points,
                    const WarningSink& warn, const std::vector<std::string>& columns,
                    OpenedModel& out, Fn&& fn, bool positions_only = false) {
  BatchesAhead batches(files, batch_points, warn, columns, positions_only);
  for (;;) {
    auto [batch, file] = batches.next();
    if (batch.size() == 0) break;
    fn(batch, file);
  }
  out.format = batches.model().format;
  out.las = batches.model().las;
}

/// The box the files of a model declare, in the first file's frame: LAS
/// files' headers'; nullopt when one is not a LAS file.
std::optional<std::pair<glm::vec3, glm::vec3>> declared_box(
    std::span<const std::filesystem::path> files);

/// The box around the model, in the first file's frame: declared_box, or
/// the points' own (every file read) when a file declares none. The grids
/// of a build go over it (a point outside counts in the nearest cell), the
/// same in a build held whole (NeighbourReach) as in one in chunks. Read in
/// batches of BATCH_POINTS, as the passes after it read: a text cloud's
/// origin is its first batch's (TextCloudReader).
std::pair<glm::vec3, glm::vec3> model_box(std::span<const std::filesystem::path> files,
                                          const std::vector<std::string>& columns,
                                          std::size_t batch_points);

/// Geographic input is reprojected around its centre, which a chunk does
/// not know: an InputError naming FILE when FIRST (its first batch) is.
void refuse_reprojection(const PointSet& first, const std::filesystem::path& file);

/// The model's attributes as the cache records them: a field's offset as
/// the builder picks it for its whole range (node_attributes.cpp), one
/// that never varies stored once; the values span of one that varies is a
/// marker (not empty), no values.
std::vector<NodeAttribute> model_attributes(const Whole& whole);

/// A chunk's attributes in the model's order and forms: a field the chunk
/// lacks is NaN, one that varies in the model is stored per point here too
/// (so every page has the same value streams).
void match_fields(PointSet& ps, const std::vector<NodeAttribute>& model);

/// The chunk's node values moved to the model's offsets (the builder chose
/// the chunk's own; H is this build's alone, rewritten in place).
void to_model_offsets(const Hierarchy& h, const std::vector<NodeAttribute>& model);

}  // namespace treecut::detail
