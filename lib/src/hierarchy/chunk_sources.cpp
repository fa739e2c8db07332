// Reading a model for the chunked build (chunk_sources.hpp).
#include "chunk_sources.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "reproject.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::detail {

PointSet Batches::next(std::size_t max, OpenedModel& out, bool positions_only) {
  if (las_) {
    out.format = "LAS";
    out.las.info = las_->info();
    return las_->next(max, positions_only);
  }
  if (text_) {
    out.format = "text";
    return text_->next(max);
  }
  if (ply_ && ply_->streams()) {
    out.format = "PLY";
    PointSet batch = ply_->next(max);
    out.ply = ply_->report();
    return batch;
  }
  if (pcd_ && pcd_->streams()) {
    out.format = "PCD";
    return pcd_->next(max);
  }
  if (done_) return {};
  done_ = true;
  PointSet all = read_point_file(file_, out, warn_, columns_);
  if (!all.triangles.empty())
    throw InputError(quoted_name(file_) +
                     ": a mesh is built held in memory (its faces join points that chunks "
                     "would part); --memory SIZE with room for it");
  return all;
}

BatchesAhead::BatchesAhead(std::span<const std::filesystem::path> files, std::size_t batch_points,
                           const WarningSink& warn, const std::vector<std::string>& columns,
                           bool positions_only)
    : warn_(warn) {
  reader_ = std::thread([this, files, batch_points, &columns, positions_only] {
    try {
      read(files, batch_points, columns, positions_only);
    } catch (...) {
      std::lock_guard lock(mutex_);
      slot_.error = std::current_exception();
      slot_.full = true;
      changed_.notify_all();
    }
  });
}

BatchesAhead::~BatchesAhead() {
  {
    std::lock_guard lock(mutex_);
    slot_.stop = true;
  }
  changed_.notify_all();
  reader_.join();
}

void BatchesAhead::read(std::span<const std::filesystem::path> files, std::size_t batch_points,
                        const std::vector<std::string>& columns, bool positions_only) {
  std::vector<std::string> warnings;  // the reader's since the last batch
  const WarningSink keep = [&](const std::string& w) { warnings.push_back(w); };
  // Hands a batch (or the end) over once the caller took the one before;
  // false when the caller stopped.
  const auto hand_over = [&](PointSet batch, std::size_t file, bool end) {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !slot_.full || slot_.stop; });
    if (slot_.stop) return false;
    slot_.batch = std::move(batch), slot_.file = file, slot_.end = end;
    slot_.warnings = std::exchange(warnings, {});
    slot_.full = true;
    changed_.notify_all();
    return true;
  };
  // Waits for the slot to empty before reading on, so that two batches at
  // most are held.
  const auto wanted = [&] {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !slot_.full || slot_.stop; });
    return !slot_.stop;
  };
  for (std::size_t f = 0; f < files.size(); ++f) {
    Batches batches(files[f], warn_ ? keep : WarningSink{}, columns);
    OpenedModel one;
    for (;;) {
      if (!wanted()) return;
      PointSet batch = batches.next(batch_points, f == 0 ? model_ : one, positions_only);
      if (batch.size() == 0) break;
      if (!hand_over(std::move(batch), f, false)) return;
    }
    if (f > 0) model_.las.dropped_nonfinite += one.las.dropped_nonfinite;
  }
  hand_over({}, files.size(), true);
}

std::pair<PointSet, std::size_t> BatchesAhead::next() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return slot_.full; });
  if (slot_.error) std::rethrow_exception(slot_.error);
  std::vector<std::string> warnings = std::move(slot_.warnings);
  std::pair<PointSet, std::size_t> out{std::move(slot_.batch), slot_.file};
  slot_.batch = {};
  if (!slot_.end) slot_.full = false;  // the end stays for a later call
  changed_.notify_all();
  lock.unlock();
  for (const std::string& w : warnings) warn_(w);
  return out;
}

void join_frame(PointSet& batch, const std::filesystem::path& file,
                const std::filesystem::path& first_file, Whole& whole, const WarningSink& warn) {
  if (!whole.started) {
    whole.first.frame = batch.frame;
    whole.first.records = batch.records;
    whole.first.adjusted_gps_time = batch.adjusted_gps_time;
    whole.started = true;
  } else {
    check_same_system(first_file, whole.first, file, batch, warn);
    CoordinateFrame& f = whole.first.frame;
    if (f.resolution != batch.frame.resolution || f.grid_offset != batch.frame.grid_offset)
      f.resolution = glm::dvec3(0.0), f.grid_offset = glm::dvec3(0.0);
  }
  const glm::dvec3 shift = batch.frame.origin - whole.first.frame.origin;
  for (glm::vec3& p : batch.positions) p = glm::vec3(glm::dvec3(p) + shift);
  std::vector<glm::dvec3>().swap(batch.exact_positions);  // the hierarchy is floats
  batch.frame.origin = whole.first.frame.origin;
}

void gather(const PointSet& b, Whole& whole) {
  for (const glm::vec3& p : b.positions) {
    whole.sum += glm::dvec3(p);
    whole.lo = glm::min(whole.lo, p), whole.hi = glm::max(whole.hi, p);
  }
  whole.normals = whole.normals && b.has_normals();
  whole.radii = whole.radii && b.has_radii();
  whole.curvature = whole.curvature && b.has_curvature();
  const bool earlier = whole.points > 0;
  for (const PointAttribute& a : b.attributes) {
    const bool known = std::any_of(whole.fields.begin(), whole.fields.end(),
                                   [&](const Whole::Field& f) { return f.name == a.name; });
    if (known || whole.fields.size() == kMaxAttributes) continue;
    Whole::Field& f = whole.fields.emplace_back();
    f.name = a.name, f.kind = a.kind;
    if (earlier) f.add(std::numeric_limits<double>::quiet_NaN());  // the earlier points lack it
  }
  for (Whole::Field& f : whole.fields) {
    const auto it = std::find_if(b.attributes.begin(), b.attributes.end(),
                                 [&](const PointAttribute& a) { return a.name == f.name; });
    if (it == b.attributes.end() || it->is_constant()) {
      f.add(it == b.attributes.end() ? std::numeric_limits<double>::quiet_NaN() : it->constant);
      continue;
    }
    for (std::size_t i = 0; i < b.size(); ++i) f.add(it->value(i));
  }
  whole.points += b.size();
}

std::optional<std::pair<glm::vec3, glm::vec3>> declared_box(
    std::span<const std::filesystem::path> files) {
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  std::optional<glm::dvec3> origin;
  for (const std::filesystem::path& file : files) {
    if (!read_head(file, 4).starts_with("LASF")) return std::nullopt;
    LasReader reader(file);
    const LasInfo& info = reader.info();
    if (!origin) origin = reader.next(0).frame.origin;
    if (info.point_count == 0) continue;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], static_cast<float>(info.min[a] - (*origin)[a]));
      hi[a] = std::max(hi[a], static_cast<float>(info.max[a] - (*origin)[a]));
    }
  }
  if (!(lo.x <= hi.x)) lo = hi = glm::vec3(0.0f);
  return std::pair{lo, hi};
}

std::pair<glm::vec3, glm::vec3> model_box(std::span<const std::filesystem::path> files,
                                          const std::vector<std::string>& columns,
                                          std::size_t batch_points) {
  if (const auto box = declared_box(files)) return *box;
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  Whole frame_only;
  OpenedModel ignored;
  for_each_batch(
      files, batch_points, {}, columns, ignored,
      [&](PointSet& b, std::size_t f) {
        join_frame(b, files[f], files.front(), frame_only, {});
        for (const glm::vec3& p : b.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
      },
      true);
  if (!(lo.x <= hi.x)) lo = hi = glm::vec3(0.0f);
  return {lo, hi};
}

void refuse_reprojection(const PointSet& first, const std::filesystem::path& file) {
  PointSet one;
  one.frame = first.frame;
  one.positions.assign(first.positions.begin(), first.positions.begin() + 1);
  if (!reproject(one, {}, quoted_name(file)).empty())
    throw InputError(quoted_name(file) +
                     ": geographic coordinates are reprojected in a build held in memory; this "
                     "model needs more than its memory budget (--memory SIZE)");
}

std::vector<NodeAttribute> model_attributes(const Whole& whole) {
  static const float kVaries = 0.0f;  // a non-empty span marks a field that varies
  std::vector<NodeAttribute> out;
  for (const Whole::Field& f : whole.fields) {
    NodeAttribute a;
    a.name = f.name, a.kind = f.kind;
    const bool any = f.lo <= f.hi;
    a.min = any ? f.lo : std::numeric_limits<double>::quiet_NaN();
    a.max = any ? f.hi : std::numeric_limits<double>::quiet_NaN();
    if (!f.varies) {
      a.offset = std::isnan(f.first) || std::fabs(f.first) < 16777216.0 ? 0.0 : std::round(f.first);
      a.constant = static_cast<float>(f.first - a.offset);
    } else {
      const double mid = any ? std::round(0.5 * f.lo + 0.5 * f.hi) : 0.0;
      a.offset = !any || (std::fabs(mid) < 16777216.0 && f.lo == std::round(f.lo) &&
                          f.hi == std::round(f.hi))
                     ? 0.0
                     : mid;
      a.values = std::span<const float>(&kVaries, 1);
    }
    out.push_back(std::move(a));
  }
  return out;
}

void match_fields(PointSet& ps, const std::vector<NodeAttribute>& model) {
  std::vector<PointAttribute> fields;
  for (const NodeAttribute& m : model) {
    auto it = std::find_if(ps.attributes.begin(), ps.attributes.end(),
                           [&](const PointAttribute& a) { return a.name == m.name; });
    PointAttribute a;
    if (it != ps.attributes.end()) a = std::move(*it);
    a.name = m.name, a.kind = m.kind;
    if (a.is_constant() && !m.is_constant()) a.wide.assign(ps.size(), a.constant);
    fields.push_back(std::move(a));
  }
  ps.attributes = std::move(fields);
}

void to_model_offsets(const Hierarchy& h, const std::vector<NodeAttribute>& model) {
  for (std::size_t k = 0; k < model.size(); ++k) {
    const NodeAttribute& own = h.attributes()[k];
    if (own.is_constant() || own.offset == model[k].offset) continue;
    auto* v = const_cast<float*>(own.values.data());
    for (std::size_t i = 0; i < own.values.size(); ++i)
      if (!std::isnan(v[i])) v[i] = static_cast<float>(own.offset + double(v[i]) - model[k].offset);
  }
}

}  // namespace treecut::detail
