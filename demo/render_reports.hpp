// What `treecut render` writes besides the frames: the rows it records per
// frame, stats.csv, summary.json and plot.svg (docs/rendering.md documents
// the columns and keys), and the guard of the output folder (what --out may
// write into). The run loop is in render_commands.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "treecut/counters.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/query_executor.hpp"

namespace treecut::cli {

struct FrameRow {
  int frame = 0;
  double time_s = 0.0;
  double frame_ms = 0.0;
  std::size_t cut_size = 0;  // splats drawn: the nodes of the cut
  std::uint64_t points = 0;  // points represented: the leaves under them
  double iteration_ms = 0.0;
  std::uint64_t exchanges = 0;
  std::uint64_t iterations = 0;
  bool converged = false;
  double psnr_db = std::numeric_limits<double>::quiet_NaN();
  // The strategy's GPU queries in this frame (QueryExecutor): 0 for a
  // strategy that posts none.
  std::uint64_t queries_issued = 0;
  std::uint64_t queries_answered = 0;
  std::size_t queries_pending = 0;         // issued, not yet answered, after the frame
  double query_latency_frames_mean = 0.0;  // of this frame's answers (0: none)
  std::uint64_t query_latency_frames_max = 0;
  double query_cpu_us = 0.0;  // the executor's render-thread CPU time
  // --psnr: luminance PSNR against full detail, capped at kLumaPsnrCap (never
  // inf); NaN when not measured.
  double psnr_luma_db = std::numeric_limits<double>::quiet_NaN();
  // The strategy's named counters (treecut/counters.hpp) of the last
  // iteration completed at this frame (with --sync, the one after it).
  Counters counters;
  // A scene (objects > 0): draw calls of the frame and the render thread's
  // CPU time for it (summary.json's "scene" block).
  std::size_t objects = 0;
  std::size_t draw_calls = 0;
  double render_cpu_ms = 0.0;
};

/// Luminance PSNR (Y = 0.299 R + 0.587 G + 0.114 B, BT.601, peak 255) of two
/// images of the same size, capped: identical images give kLumaPsnrCap, so
/// the column and its mean stay finite.
inline constexpr double kLumaPsnrCap = 99.0;
double luma_psnr(const splat::Image& a, const splat::Image& b);

struct RunSummary {
  std::string strategy;
  std::string renderer;  ///< GL_RENDERER / GL_VERSION (back end)
  std::vector<FrameRow> rows;
  double stability_changed = std::numeric_limits<double>::quiet_NaN();  // mean fraction
  double stability_max = std::numeric_limits<double>::quiet_NaN();
  int stability_frames = 0;
  bool stability_converged = false;
  double converged_psnr = std::numeric_limits<double>::quiet_NaN();
  std::size_t converged_cut = 0;
  // The executor's totals at the end of the run (warm-up and stability frames
  // included), over `query_frames` frames.
  splat::QueryStats queries;
  std::uint64_t query_frames = 0;
  // A scene: its objects and distinct models, the per-object state's nodes,
  // the peak resident memory at the end of the run (summary.json "scene").
  std::size_t objects = 0;
  std::size_t models = 0;
  std::uint64_t object_nodes = 0;
  double peak_rss_mib = 0.0;
};

/// The mean of a field over the rows where it is finite; NaN if none is.
double mean_of(const std::vector<FrameRow>& rows, double FrameRow::*field);
double median_frame_ms(const std::vector<FrameRow>& rows);
/// The frame time that 99 % of the frames do not exceed (nearest rank).
double p99_frame_ms(const std::vector<FrameRow>& rows);
/// The mean over the frames that differ from full detail; +infinity when every
/// measured frame was identical to it, NaN when none was measured.
double mean_psnr(const std::vector<FrameRow>& rows);
/// "inf" for +infinity, "" for NaN (not measured), else six significant digits.
std::string psnr_text(double v);

/// stats.csv: the header, one row per frame (write_file_atomically).
void write_stats_csv(const std::filesystem::path& file, const std::vector<FrameRow>& rows);
/// The named counters of a run's rows: name and unit in the order first
/// published, with the sum and the frames that had each.
struct CounterSeries {
  std::string name, unit;
  double total = 0.0;
  double max = 0.0;  ///< the largest value a frame had (a budget's peak)
  std::size_t frames = 0;
};
std::vector<CounterSeries> counter_series(const std::vector<FrameRow>& rows);
/// "NAME MEAN UNIT, ..." per frame of every named counter ("" for none).
std::string counters_line(const std::vector<FrameRow>& rows);
/// The text of summary.json.
std::string summary_json(const RunSummary& s);
/// Stacked panels over the frame index, one line per strategy: frame time,
/// splats drawn, and PSNR when measured; 1-2-5 ticks, a legend per panel.
std::string plot_svg(const std::vector<RunSummary>& runs, const std::string& title);
/// plot_svg written atomically.
void write_plot_svg(const std::filesystem::path& file, const std::vector<RunSummary>& runs,
                    const std::string& title);

/// Refuses (InputError), before any work: an --out that is not a missing or
/// empty folder or an earlier render's output (its marker or stats.csv at its
/// top), a strategy given twice, an entry render would replace that is not a
/// regular file, a strategy's subfolder that is a link, and INPUTS (the
/// model, the camera path) inside the output folder.
void check_output_folder(const std::filesystem::path& out,
                         const std::vector<std::string>& strategies,
                         const std::vector<std::filesystem::path>& inputs);
void make_output_folder(const std::filesystem::path& dir);
/// Writes the marker that makes `out` recognizably an earlier render's output.
void mark_output_folder(const std::filesystem::path& out);

}  // namespace treecut::cli
