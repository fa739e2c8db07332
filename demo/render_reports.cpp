#include "render_reports.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <system_error>

#include "ticks.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::cli {

namespace {

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// A counter's value in stats.csv: the shortest text that reads back as the
// same double, so a count prints whole ("1234567", never "1.23457e+06").
std::string counter_text(double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, end) : std::string();
}

nlohmann::ordered_json psnr_json(double v) {
  if (std::isinf(v) && v > 0) return "inf";
  if (!std::isfinite(v)) return nullptr;
  return std::strtod(json_number(v).c_str(), nullptr);
}

// Six significant digits as before; null for a NaN (not measured).
nlohmann::ordered_json number_json(double v) {
  if (!std::isfinite(v)) return nullptr;
  return std::strtod(json_number(v).c_str(), nullptr);
}

std::size_t identical_frames(const std::vector<FrameRow>& rows) {
  return static_cast<std::size_t>(std::count_if(rows.begin(), rows.end(), [](const FrameRow& r) {
    return std::isinf(r.psnr_db) && r.psnr_db > 0;
  }));
}

// What `render --out DIR` may write into: a missing or empty folder, or one an
// earlier render wrote (its marker, or the stats.csv an older treecut wrote).
// Anything else is the user's and is refused before any work.
constexpr const char* kRenderMarker = ".treecut-render";

bool starts_with_stats_header(const std::filesystem::path& file) {
  // Only the header line matters (a long run's table may be large).
  return file_starts_with(file, "frame,time_s,frame_ms,");
}

// The marker, or the stats.csv of an older treecut, at the folder's own top:
// a render output somewhere below it (proj/old/stats.csv) does not make the
// user's proj/plot.svg treecut's to replace.
bool is_earlier_render_output(const std::filesystem::path& dir) {
  return file_kind(dir / kRenderMarker) == FileKind::Regular ||
         starts_with_stats_header(dir / "stats.csv");
}

// A name render writes in a folder: frame_NNNNN.png, stats.csv, summary.json,
// plot.svg, the marker.
bool is_render_output_name(const std::string& name) {
  if (name == "stats.csv" || name == "summary.json" || name == "plot.svg" || name == kRenderMarker)
    return true;
  return name.size() >= 15 && name.starts_with("frame_") && name.ends_with(".png") &&
         std::all_of(name.begin() + 6, name.end() - 4, [](char c) { return c >= '0' && c <= '9'; });
}

// Every entry of DIR that render would replace must be a regular file (a
// directory or FIFO found mid-run would end it after frames were written).
void check_output_entries(const std::filesystem::path& dir) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    if (!is_render_output_name(e.path().filename().string())) continue;
    const auto status = e.symlink_status(ec);
    if (std::filesystem::is_regular_file(status)) continue;
    // A link is the user's (render never makes one), whatever it points to.
    const std::string what = std::filesystem::is_symlink(status)
                                 ? std::string("a symbolic link")
                                 : std::string(describe(file_kind(e.path())));
    throw InputError(quoted_name(e.path()) + ": is " + what +
                     "; refusing to write render output there");
  }
}

}  // namespace

double mean_of(const std::vector<FrameRow>& rows, double FrameRow::*field) {
  double s = 0.0;
  std::size_t n = 0;
  for (const FrameRow& r : rows) {
    if (std::isfinite(r.*field)) {
      s += r.*field;
      ++n;
    }
  }
  return n > 0 ? s / double(n) : std::numeric_limits<double>::quiet_NaN();
}

double median_frame_ms(const std::vector<FrameRow>& rows) {
  std::vector<double> v;
  for (const FrameRow& r : rows) v.push_back(r.frame_ms);
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double p99_frame_ms(const std::vector<FrameRow>& rows) {
  std::vector<double> v;
  for (const FrameRow& r : rows) v.push_back(r.frame_ms);
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::ptrdiff_t>((v.size() * 99 + 99) / 100 - 1);  // ceil(0.99 n) - 1
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}

// PSNR of identical images is +infinity: "inf" in stdout, stats.csv and
// summary.json (a JSON string there; float("inf") reads all three back), an
// empty field / null when it was not measured.
std::string psnr_text(double v) {
  if (std::isinf(v) && v > 0) return "inf";
  return std::isfinite(v) ? json_number(v) : std::string();
}

// The mean over the frames that differ from full detail; +infinity when every
// measured frame was identical to it, NaN when none was measured.
double mean_psnr(const std::vector<FrameRow>& rows) {
  double sum = 0.0;
  std::size_t finite = 0, identical = 0;
  for (const FrameRow& r : rows) {
    if (std::isfinite(r.psnr_db)) {
      sum += r.psnr_db;
      ++finite;
    } else if (std::isinf(r.psnr_db)) {
      ++identical;
    }
  }
  if (finite > 0) return sum / double(finite);
  return identical > 0 ? std::numeric_limits<double>::infinity()
                       : std::numeric_limits<double>::quiet_NaN();
}

double luma_psnr(const splat::Image& a, const splat::Image& b) {
  if (a.width != b.width || a.height != b.height || a.rgba.size() != b.rgba.size())
    throw std::invalid_argument("luma_psnr: images of different sizes");
  const std::size_t pixels = a.rgba.size() / 4;
  double sum = 0.0;
  for (std::size_t i = 0; i < pixels; ++i) {
    const std::uint8_t* p = &a.rgba[i * 4];
    const std::uint8_t* q = &b.rgba[i * 4];
    const double d = 0.299 * (double(p[0]) - q[0]) + 0.587 * (double(p[1]) - q[1]) +
                     0.114 * (double(p[2]) - q[2]);
    sum += d * d;
  }
  if (pixels == 0 || sum == 0.0) return kLumaPsnrCap;
  return std::min(kLumaPsnrCap, 10.0 * std::log10(255.0 * 255.0 * double(pixels) / sum));
}

std::vector<CounterSeries> counter_series(const std::vector<FrameRow>& rows) {
  std::vector<CounterSeries> series;
  for (const FrameRow& r : rows) {
    for (const Counter& c : r.counters.items()) {
      auto it = std::find_if(series.begin(), series.end(),
                             [&](const CounterSeries& x) { return x.name == c.name(); });
      if (it == series.end()) {
        series.push_back({std::string(c.name()), std::string(c.unit()), 0.0, c.value, 0});
        it = series.end() - 1;
      }
      it->total += c.value;
      it->max = std::max(it->max, c.value);
      ++it->frames;
    }
  }
  return series;
}

std::string counters_line(const std::vector<FrameRow>& rows) {
  std::string line;
  for (const CounterSeries& c : counter_series(rows)) {
    char value[64];
    std::snprintf(value, sizeof value, "%.3g",
                  c.total / double(std::max<std::size_t>(c.frames, 1)));
    line += (line.empty() ? "per frame " : ", ") + c.name + " " + value +
            (c.unit.empty() ? "" : " " + c.unit);
  }
  return line;
}

void write_stats_csv(const std::filesystem::path& file, const std::vector<FrameRow>& rows) {
  std::ostringstream out;
  // The query columns, then the luminance PSNR, then one column per named
  // counter of the strategy (treecut/counters.hpp), in the order first
  // published: an older reader of the first ones still works.
  const std::vector<CounterSeries> series = counter_series(rows);
  out << "frame,time_s,frame_ms,splats_drawn,points_represented,iteration_ms,exchanges,iterations,"
         "converged,psnr_db,queries_issued,queries_answered,queries_pending,"
         "query_latency_frames_mean,query_latency_frames_max,query_cpu_us,psnr_luma_db";
  for (const CounterSeries& c : series) out << ',' << c.name;
  out << '\n';
  for (const FrameRow& r : rows) {
    out << r.frame << ',' << r.time_s << ',' << r.frame_ms << ',' << r.cut_size << ',' << r.points
        << ',' << r.iteration_ms << ',' << r.exchanges << ',' << r.iterations << ','
        << (r.converged ? 1 : 0) << ',' << psnr_text(r.psnr_db) << ',' << r.queries_issued << ','
        << r.queries_answered << ',' << r.queries_pending << ',' << r.query_latency_frames_mean
        << ',' << r.query_latency_frames_max << ',' << r.query_cpu_us << ','
        << (std::isfinite(r.psnr_luma_db) ? json_number(r.psnr_luma_db) : std::string());
    for (const CounterSeries& c : series) {
      out << ',';
      if (const std::optional<double> v = r.counters.find(c.name)) out << counter_text(*v);
    }
    out << '\n';
  }
  write_file_atomically(file, out.str());
}

std::string summary_json(const RunSummary& s) {
  std::size_t cut_sum = 0;
  std::uint64_t points_sum = 0;
  for (const FrameRow& r : s.rows) {
    cut_sum += r.cut_size;
    points_sum += r.points;
  }
  const double n = std::max<double>(1.0, double(s.rows.size()));
  nlohmann::ordered_json j;
  j["written_by"] = "treecut render";
  j["strategy"] = s.strategy;
  j["renderer"] = s.renderer;
  j["frames"] = s.rows.size();
  j["mean_frame_ms"] = number_json(mean_of(s.rows, &FrameRow::frame_ms));
  j["median_frame_ms"] = number_json(median_frame_ms(s.rows));
  j["p99_frame_ms"] = number_json(p99_frame_ms(s.rows));
  j["mean_splats_drawn"] = number_json(double(cut_sum) / n);
  j["mean_points_represented"] = number_json(double(points_sum) / n);
  j["mean_iteration_ms"] = number_json(mean_of(s.rows, &FrameRow::iteration_ms));
  j["exchanges"] = s.rows.empty() ? 0 : s.rows.back().exchanges;
  j["mean_psnr_db"] = psnr_json(mean_psnr(s.rows));
  j["psnr_identical_frames"] = identical_frames(s.rows);
  j["mean_psnr_luma_db"] = number_json(mean_of(s.rows, &FrameRow::psnr_luma_db));
  j["stability"] = {{"frames", s.stability_frames},
                    {"converged", s.stability_converged},
                    {"mean_changed_fraction", number_json(s.stability_changed)},
                    {"max_changed_fraction", number_json(s.stability_max)},
                    {"splats_drawn", s.converged_cut},
                    {"psnr_db", psnr_json(s.converged_psnr)}};
  // The strategy's named counters: unit, mean per frame that had it, total.
  if (const std::vector<CounterSeries> series = counter_series(s.rows); !series.empty()) {
    nlohmann::ordered_json counters = nlohmann::ordered_json::object();
    for (const CounterSeries& c : series) {
      // Full doubles (counters are finite): a total of counts stays exact.
      counters[c.name] = {{"unit", c.unit},
                          {"mean", c.total / double(std::max<std::size_t>(c.frames, 1))},
                          {"total", c.total},
                          {"max", c.max},
                          {"frames", c.frames}};
    }
    j["counters"] = std::move(counters);
  }
  // A scene's block: objects, draw calls and render-thread CPU per frame.
  if (s.objects > 0) {
    double calls = 0, cpu = 0;
    std::size_t calls_max = 0;
    for (const FrameRow& r : s.rows) {
      calls += double(r.draw_calls);
      calls_max = std::max(calls_max, r.draw_calls);
      cpu += r.render_cpu_ms;
    }
    j["scene"] = {{"objects", s.objects},
                  {"models", s.models},
                  {"object_nodes", s.object_nodes},
                  {"mean_draw_calls", number_json(calls / n)},
                  {"max_draw_calls", calls_max},
                  {"mean_render_cpu_ms", number_json(cpu / n)},
                  {"peak_rss_mib", number_json(s.peak_rss_mib)}};
  }
  // The executor's totals (zeros for a strategy that posts no queries).
  const splat::QueryStats& q = s.queries;
  j["queries"] = {
      {"issued", q.issued},
      {"answered", q.answered},
      {"occluded", q.occluded},
      {"pending", q.pending},
      {"queued", q.queued},
      {"dropped", q.dropped},
      {"batches", q.batches},
      {"latency_frames_mean", number_json(q.latency_frames_mean())},
      {"latency_frames_max", q.latency_frames_max},
      {"frames", s.query_frames},
      {"cpu_us_per_frame", number_json(double(q.cpu_ns_total) * 1e-3 /
                                       double(std::max<std::uint64_t>(s.query_frames, 1)))}};
  return j.dump(2) + "\n";
}

void check_output_folder(const std::filesystem::path& out,
                         const std::vector<std::string>& strategies,
                         const std::vector<std::filesystem::path>& inputs) {
  std::set<std::string> seen;
  for (const std::string& name : strategies)
    if (!seen.insert(name).second)
      throw InputError("--strategy " + name +
                       " given twice: each strategy runs once (a second run would overwrite the "
                       "first one's output)");
  if (out.empty()) throw InputError("--out: an empty path (name the output folder)");
  // Render replaces files in the folder: none of its inputs may live there.
  std::error_code ec;
  const std::filesystem::path folder =
      std::filesystem::weakly_canonical(std::filesystem::absolute(out, ec), ec);
  for (const std::filesystem::path& input : inputs) {
    if (input.empty()) continue;
    std::error_code ie;
    const std::filesystem::path in =
        std::filesystem::weakly_canonical(std::filesystem::absolute(input, ie), ie);
    if (ec || ie) continue;
    const auto rel = in.lexically_relative(folder);
    if (!rel.empty() && *rel.begin() != "..")
      throw InputError(quoted_name(input) + ": is inside the output folder " + quoted_name(out) +
                       ", where render replaces files; choose another --out");
  }
  const FileKind kind = file_kind(out);
  if (kind == FileKind::Missing) return;
  if (kind != FileKind::Directory)
    throw InputError(quoted_name(out) + ": is " + std::string(describe(kind)) +
                     ", not a folder; refusing to write render output there");
  const bool empty = std::filesystem::is_empty(out, ec);
  if (ec) throw InputError(system_error_text(out, ec.value()));
  if (!empty && !is_earlier_render_output(out))
    throw InputError(quoted_name(out) +
                     ": folder is not empty and not an earlier treecut render output; refusing to "
                     "write into it");
  check_output_entries(out);
  for (const std::string& name : strategies) {
    if (strategies.size() == 1) break;
    const std::filesystem::path dir = out / name;
    // Not through a link: an earlier output's subfolder made a link to the
    // user's photos would have its frames written there.
    const auto status = std::filesystem::symlink_status(dir, ec);
    if (std::filesystem::is_symlink(status))
      throw InputError(quoted_name(dir) +
                       ": is a symbolic link; refusing to write render output through it");
    const FileKind dir_kind = file_kind(dir);
    if (dir_kind == FileKind::Missing) continue;
    if (dir_kind != FileKind::Directory)
      throw InputError(quoted_name(dir) + ": is " + std::string(describe(dir_kind)) +
                       ", not a folder; refusing to write render output there");
    if (!std::filesystem::is_empty(dir, ec) && !is_earlier_render_output(dir))
      throw InputError(quoted_name(dir) +
                       ": folder is not empty and not an earlier treecut render output; refusing "
                       "to write into it");
    check_output_entries(dir);
  }
}

void make_output_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error(system_error_text(dir, ec.value()));
}

void mark_output_folder(const std::filesystem::path& out) {
  // The marker makes the folder recognizably ours for the next run.
  if (file_kind(out / kRenderMarker) != FileKind::Regular)
    write_file_atomically(out / kRenderMarker, "written by treecut render\n");
}

// TEXT as SVG character data: a model named `a&b<c>.ply` must not make the
// plot ill-formed XML; control characters (not allowed in XML 1.0) as '?'.
std::string xml_text(std::string_view text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += static_cast<unsigned char>(c) < 0x20 ? '?' : c;
    }
  }
  return out;
}

namespace {

// A tick's label: as many decimals as the step needs, thousands and millions
// as k and M once the axis reaches 10,000 (2.5, 200 k, 1.5 M).
std::string tick_label(double v, double step, double top) {
  double scale = 1.0;
  const char* unit = "";
  if (std::abs(top) >= 1e6) {
    scale = 1e6, unit = " M";
  } else if (std::abs(top) >= 1e4) {
    scale = 1e3, unit = " k";
  }
  const int decimals = std::max(0, -static_cast<int>(std::floor(std::log10(step / scale) + 1e-9)));
  if (v == 0.0) return "0";
  char text[48];
  std::snprintf(text, sizeof text, "%.*f%s", decimals, v / scale, unit);
  return text;
}

struct PlotPanel {
  const char* name;   // the panel's id in the SVG
  const char* label;  // its title
  std::function<double(const FrameRow&)> value;
  bool from_zero;  // the y axis starts at 0 (times, counts), else at the data
};

}  // namespace

// plot.svg (issue 30): stacked panels over the frame index, one line per
// strategy: frame time, splats drawn, and PSNR against full detail when
// --psnr measured it. Each panel has 1-2-5 ticks on both axes (ticks.hpp),
// its own legend above it, and its data inset from the frame, so no line
// lies on it. Hand-written SVG: PLplot (libplplot-dev) would bring a
// library and its fonts for three line charts, and its SVG driver's layout
// is harder to hold to these rules than this function is.
std::string plot_svg(const std::vector<RunSummary>& runs, const std::string& title) {
  constexpr double kW = 900, kH = 220, kLeft = 80, kRight = 20, kTop = 44, kGap = 76;
  constexpr double kInset = 8;  // data to frame, pixels
  const char* colors[] = {"#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};
  std::vector<PlotPanel> panels = {
      {"frame_time", "frame time [ms]", [](const FrameRow& r) { return r.frame_ms; }, true},
      {"splats", "splats drawn", [](const FrameRow& r) { return double(r.cut_size); }, true}};
  bool psnr = false;
  for (const RunSummary& r : runs) {
    for (const FrameRow& row : r.rows) psnr = psnr || std::isfinite(row.psnr_db);
  }
  if (psnr) {
    panels.push_back({"psnr", "PSNR against full detail [dB] (identical frames, inf, not drawn)",
                      [](const FrameRow& r) { return r.psnr_db; }, false});
  }
  std::size_t frames = 1;
  for (const RunSummary& r : runs) frames = std::max(frames, r.rows.size());
  const double pw = kW - kLeft - kRight;
  const double last_frame = std::max<double>(1.0, double(frames) - 1.0);
  const std::vector<double> xt =
      nice_ticks(0.0, last_frame, static_cast<int>(std::min<double>(10.0, last_frame)));
  const double x_hi = xt.back();
  const auto x_of = [&](double frame) { return kLeft + kInset + (pw - 2 * kInset) * frame / x_hi; };

  std::ostringstream o;
  const double height = kTop + double(panels.size()) * (kH + kGap);
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kW << "\" height=\"" << height
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o << "<text x=\"" << kLeft << "\" y=\"20\" font-size=\"14\">" << xml_text(title) << "</text>\n";
  for (std::size_t pi = 0; pi < panels.size(); ++pi) {
    const PlotPanel& panel = panels[pi];
    const double y0 = kTop + double(pi) * (kH + kGap);
    double lo = INFINITY, hi = -INFINITY;
    for (const RunSummary& r : runs) {
      for (const FrameRow& row : r.rows) {
        const double v = panel.value(row);
        if (!std::isfinite(v)) continue;
        lo = std::min(lo, v), hi = std::max(hi, v);
      }
    }
    if (!(lo <= hi)) lo = 0.0, hi = 1.0;
    if (panel.from_zero) lo = 0.0;
    const std::vector<double> yt = nice_ticks(lo, hi, 5);
    const double y_lo = yt.front(), y_hi = yt.back(), step = yt[1] - yt[0];
    const auto y_of = [&](double v) {
      return y0 + kH - kInset - (kH - 2 * kInset) * (v - y_lo) / (y_hi - y_lo);
    };
    o << "<g class=\"panel\" id=\"" << panel.name << "\">\n";
    o << "<text x=\"" << kLeft << "\" y=\"" << y0 - 8 << "\" font-weight=\"bold\">" << panel.label
      << "</text>\n";
    // Grid and ticks first, the frame over them, the lines over both.
    for (const double t : yt) {
      const double y = y_of(t);
      o << "<line x1=\"" << kLeft << "\" x2=\"" << kLeft + pw << "\" y1=\"" << y << "\" y2=\"" << y
        << "\" stroke=\"#eee\"/><text class=\"ytick\" x=\"" << kLeft - 6 << "\" y=\"" << y + 4
        << "\" text-anchor=\"end\">" << tick_label(t, step, y_hi) << "</text>\n";
    }
    for (const double t : xt) {
      const double x = x_of(t);
      o << "<line x1=\"" << x << "\" x2=\"" << x << "\" y1=\"" << y0 + kH << "\" y2=\""
        << y0 + kH + 4 << "\" stroke=\"#888\"/><text class=\"xtick\" x=\"" << x << "\" y=\""
        << y0 + kH + 17 << "\" text-anchor=\"middle\">" << tick_label(t, xt[1] - xt[0], x_hi)
        << "</text>\n";
    }
    o << "<text x=\"" << kLeft + pw / 2 << "\" y=\"" << y0 + kH + 34
      << "\" text-anchor=\"middle\">frame</text>\n";
    o << "<rect class=\"frame\" x=\"" << kLeft << "\" y=\"" << y0 << "\" width=\"" << pw
      << "\" height=\"" << kH << "\" fill=\"none\" stroke=\"#888\"/>\n";
    for (std::size_t ri = 0; ri < runs.size(); ++ri) {
      // One polyline per run of finite values (an identical frame's inf
      // PSNR breaks it).
      const auto& rows = runs[ri].rows;
      bool open = false;
      for (std::size_t i = 0; i < rows.size(); ++i) {
        const double v = panel.value(rows[i]);
        if (!std::isfinite(v)) {
          if (open) o << "\"/>\n";
          open = false;
          continue;
        }
        if (!open) {
          o << "<polyline class=\"line\" fill=\"none\" stroke=\"" << colors[ri % 6]
            << "\" stroke-width=\"1.5\" points=\"";
          open = true;
        }
        o << x_of(double(i)) << ',' << y_of(v) << ' ';
      }
      if (open) o << "\"/>\n";
    }
    // The legend, right-aligned above the frame: it covers no data.
    o << "<g class=\"legend\">";
    double x = kLeft + pw;
    for (std::size_t ri = runs.size(); ri-- > 0;) {
      const std::string name = xml_text(runs[ri].strategy);
      x -= 30.0 + 7.0 * double(runs[ri].strategy.size());
      o << "<rect x=\"" << x << "\" y=\"" << y0 - 14 << "\" width=\"14\" height=\"4\" fill=\""
        << colors[ri % 6] << "\"/><text class=\"legend-entry\" x=\"" << x + 18 << "\" y=\""
        << y0 - 8 << "\">" << name << "</text>";
    }
    o << "</g>\n</g>\n";
  }
  o << "</svg>\n";
  return o.str();
}

void write_plot_svg(const std::filesystem::path& file, const std::vector<RunSummary>& runs,
                    const std::string& title) {
  write_file_atomically(file, plot_svg(runs, title));
}

}  // namespace treecut::cli
