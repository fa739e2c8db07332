// treecut render (headless, OSMesa) | treecut view (GLFW window).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>

#include "commands.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/model.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/frame_rate.hpp"
#include "treecut/splat/image.hpp"
#include "view_script.hpp"
#include "viewer.hpp"

namespace treecut::cli {

namespace {

struct RenderArgs {
  SceneArgs scene;
  std::string path;
  std::string out = "render-out";
  int frames = 120;
  int width = 1280;
  int height = 720;
  double orbit_seconds = 8.0;
  int warmup = 30;
  bool sync = false;
  bool psnr = false;
  int stability = 0;
  bool no_png = false;
  double target_fps = 0.0;  // > 0: the viewer's governor adapts the strategy's knob
};

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
};

struct RunSummary {
  std::string strategy;
  std::vector<FrameRow> rows;
  double stability_changed = std::numeric_limits<double>::quiet_NaN();  // mean fraction
  double stability_max = std::numeric_limits<double>::quiet_NaN();
  int stability_frames = 0;
  bool stability_converged = false;
  double converged_psnr = std::numeric_limits<double>::quiet_NaN();
  std::size_t converged_cut = 0;
};

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

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// PSNR of identical images is +infinity: "inf" in stdout, stats.csv and
// summary.json (a JSON string there; float("inf") reads all three back), an
// empty field / null when it was not measured.
std::string psnr_text(double v) {
  if (std::isinf(v) && v > 0) return "inf";
  return std::isfinite(v) ? json_number(v) : std::string();
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

std::size_t identical_frames(const std::vector<FrameRow>& rows) {
  return static_cast<std::size_t>(std::count_if(rows.begin(), rows.end(), [](const FrameRow& r) {
    return std::isinf(r.psnr_db) && r.psnr_db > 0;
  }));
}

void write_csv(const std::filesystem::path& file, const std::vector<FrameRow>& rows) {
  std::ostringstream out;
  out << "frame,time_s,frame_ms,splats_drawn,points_represented,iteration_ms,exchanges,iterations,"
         "converged,psnr_db\n";
  for (const FrameRow& r : rows) {
    out << r.frame << ',' << r.time_s << ',' << r.frame_ms << ',' << r.cut_size << ',' << r.points
        << ',' << r.iteration_ms << ',' << r.exchanges << ',' << r.iterations << ','
        << (r.converged ? 1 : 0) << ',' << psnr_text(r.psnr_db) << '\n';
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
  j["frames"] = s.rows.size();
  j["mean_frame_ms"] = number_json(mean_of(s.rows, &FrameRow::frame_ms));
  j["median_frame_ms"] = number_json(median_frame_ms(s.rows));
  j["mean_splats_drawn"] = number_json(double(cut_sum) / n);
  j["mean_points_represented"] = number_json(double(points_sum) / n);
  j["mean_iteration_ms"] = number_json(mean_of(s.rows, &FrameRow::iteration_ms));
  j["exchanges"] = s.rows.empty() ? 0 : s.rows.back().exchanges;
  j["mean_psnr_db"] = psnr_json(mean_psnr(s.rows));
  j["psnr_identical_frames"] = identical_frames(s.rows);
  j["stability"] = {{"frames", s.stability_frames},
                    {"converged", s.stability_converged},
                    {"mean_changed_fraction", number_json(s.stability_changed)},
                    {"max_changed_fraction", number_json(s.stability_max)},
                    {"splats_drawn", s.converged_cut},
                    {"psnr_db", psnr_json(s.converged_psnr)}};
  return j.dump(2) + "\n";
}

// What `render --out DIR` may write into: a missing or empty folder, or one an
// earlier render wrote (its marker, or the stats.csv an older treecut wrote).
// Anything else is the user's and is refused before any work.
constexpr const char* kRenderMarker = ".treecut-render";

bool starts_with_stats_header(const std::filesystem::path& file) {
  if (file_kind(file) != FileKind::Regular) return false;
  // Only the header line matters (a long run's table may be large); opened
  // without blocking, as every input.
  int fd = -1;
  try {
    fd = open_regular_file(file);
  } catch (const std::exception&) {
    return false;
  }
  constexpr std::string_view kHeader = "frame,time_s,frame_ms,";
  char head[kHeader.size()] = {};
  const ssize_t n = ::read(fd, head, sizeof head);
  ::close(fd);
  return n == static_cast<ssize_t>(sizeof head) && std::string_view(head, sizeof head) == kHeader;
}

bool is_earlier_render_output(const std::filesystem::path& dir) {
  if (file_kind(dir / kRenderMarker) == FileKind::Regular) return true;
  if (starts_with_stats_header(dir / "stats.csv")) return true;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec))
    if (e.is_directory(ec) && starts_with_stats_header(e.path() / "stats.csv")) return true;
  return false;
}

void check_output_target(const std::filesystem::path& file) {
  const FileKind kind = file_kind(file);
  if (kind != FileKind::Missing && kind != FileKind::Regular)
    throw InputError(file.string() + ": is " + std::string(describe(kind)) +
                     "; refusing to write render output there");
}

void check_output_folder(const std::filesystem::path& out,
                         const std::vector<std::string>& strategies) {
  std::set<std::string> seen;
  for (const std::string& name : strategies)
    if (!seen.insert(name).second)
      throw InputError("--strategy " + name +
                       " given twice: each strategy runs once (a second run would overwrite the "
                       "first one's output)");
  const FileKind kind = file_kind(out);
  if (kind == FileKind::Missing) return;
  if (kind != FileKind::Directory)
    throw InputError(out.string() + ": is " + std::string(describe(kind)) +
                     ", not a folder; refusing to write render output there");
  std::error_code ec;
  const bool empty = std::filesystem::is_empty(out, ec);
  if (ec) throw InputError(system_error_text(out, ec.value()));
  if (!empty && !is_earlier_render_output(out))
    throw InputError(out.string() +
                     ": folder is not empty and not an earlier treecut render output; refusing to "
                     "write into it");
  check_output_target(out / "plot.svg");
  for (const std::string& name : strategies) {
    const std::filesystem::path dir = strategies.size() > 1 ? out / name : out;
    const FileKind dir_kind = file_kind(dir);
    if (dir_kind != FileKind::Missing && dir_kind != FileKind::Directory)
      throw InputError(dir.string() + ": is " + std::string(describe(dir_kind)) +
                       ", not a folder; refusing to write render output there");
    check_output_target(dir / "stats.csv");
    check_output_target(dir / "summary.json");
  }
}

void make_output_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error(system_error_text(dir, ec.value()));
}

// Two stacked charts (frame time, cut size) over the frame index, one line per
// strategy: the plot of the README's benchmark section.
void write_plot_svg(const std::filesystem::path& file, const std::vector<RunSummary>& runs,
                    const std::string& title) {
  constexpr double kW = 900, kH = 260, kLeft = 70, kRight = 20, kTop = 40, kGap = 50;
  const char* colors[] = {"#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};
  std::ostringstream o;
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kW << "\" height=\""
    << kTop + 2 * kH + kGap + 40 << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o << "<text x=\"" << kLeft << "\" y=\"20\" font-size=\"14\">" << title << "</text>\n";
  auto chart = [&](int index, const char* label, auto value) {
    const double y0 = kTop + index * (kH + kGap);
    double vmax = 0.0;
    std::size_t frames = 1;
    for (const RunSummary& r : runs) {
      frames = std::max(frames, r.rows.size());
      for (const FrameRow& row : r.rows) vmax = std::max(vmax, double(value(row)));
    }
    if (vmax <= 0.0) vmax = 1.0;
    const double pw = kW - kLeft - kRight;
    o << "<rect x=\"" << kLeft << "\" y=\"" << y0 << "\" width=\"" << pw << "\" height=\"" << kH
      << "\" fill=\"none\" stroke=\"#888\"/>\n";
    o << "<text x=\"" << kLeft << "\" y=\"" << y0 - 6 << "\">" << label << " (max "
      << json_number(vmax) << ")</text>\n";
    for (int t = 0; t <= 4; ++t) {
      const double y = y0 + kH - kH * t / 4.0;
      o << "<text x=\"" << kLeft - 6 << "\" y=\"" << y + 4 << "\" text-anchor=\"end\">"
        << json_number(vmax * t / 4.0) << "</text>\n";
    }
    o << "<text x=\"" << kLeft + pw / 2 << "\" y=\"" << y0 + kH + 16
      << "\" text-anchor=\"middle\">frame</text>\n";
    for (std::size_t ri = 0; ri < runs.size(); ++ri) {
      o << "<polyline fill=\"none\" stroke=\"" << colors[ri % 6]
        << "\" stroke-width=\"1.5\" points=\"";
      const auto& rows = runs[ri].rows;
      for (std::size_t i = 0; i < rows.size(); ++i) {
        const double x = kLeft + pw * double(i) / double(std::max<std::size_t>(frames - 1, 1));
        const double y = y0 + kH - kH * double(value(rows[i])) / vmax;
        o << x << ',' << y << ' ';
      }
      o << "\"/>\n";
    }
  };
  chart(0, "frame time [ms]", [](const FrameRow& r) { return r.frame_ms; });
  chart(1, "cut size [nodes]", [](const FrameRow& r) { return double(r.cut_size); });
  for (std::size_t ri = 0; ri < runs.size(); ++ri) {
    const double x = kLeft + 150.0 * double(ri);
    const double y = kTop + 2 * kH + kGap + 30;
    o << "<rect x=\"" << x << "\" y=\"" << y - 10 << "\" width=\"14\" height=\"4\" fill=\""
      << colors[ri % 6] << "\"/><text x=\"" << x + 20 << "\" y=\"" << y - 5 << "\">"
      << runs[ri].strategy << "</text>\n";
  }
  o << "</svg>\n";
  write_file_atomically(file, o.str());
}

void run_render(const RenderArgs& a) {
  if (a.frames < 1) throw InputError("--frames must be at least 1");
  const splat::RenderSettings settings = render_settings(a.scene);  // validates --mode early
  const StrategyRegistry registry = make_registry(a.scene);
  check_params(registry, a.scene.strategies, a.scene.params);  // exit 2 before any work
  for (const std::string& name : a.scene.strategies) {
    if (a.target_fps > 0.0 &&
        !splat::FrameRateGovernor::for_strategy(*make_strategy(registry, name, {}), 1)) {
      throw InputError(name + ": --target-fps needs a max_nodes or min_size parameter");
    }
  }
  check_output_folder(a.out, a.scene.strategies);
  const float aspect = float(a.width) / float(a.height);
  splat::CameraPath path;
  if (!a.path.empty()) path = splat::load_camera_path(a.path);

  const Scene scene = load_scene(a.scene);
  const Hierarchy& h = *scene.hierarchy;
  if (a.path.empty())
    path = splat::orbit_path(h.bounds_min(), h.bounds_max(), aspect, a.orbit_seconds, 73, scene.up);
  std::printf("model     %s: %u points, %u nodes\n", scene.label.c_str(), h.leaf_count(),
              h.node_count());

  splat::OsmesaContext context(a.width, a.height);
  std::printf("renderer  %s, %dx%d, %s splats\n", splat::GlContext::renderer_string().c_str(),
              a.width, a.height, std::string(splat::splat_mode_name(settings.mode)).c_str());
  splat::Renderer renderer(h, {a.width, a.height});
  const glm::ivec2 size(a.width, a.height);
  splat::CutBuffer full;
  if (a.psnr || a.stability > 0) full.upload(h, TreeCut::leaf_cut(h).nodes());
  auto grab = [&] { return splat::Image{a.width, a.height, renderer.read_pixels()}; };

  const std::filesystem::path out(a.out);
  make_output_folder(out);
  // The marker makes the folder recognizably ours for the next run.
  if (file_kind(out / kRenderMarker) != FileKind::Regular)
    write_file_atomically(out / kRenderMarker, "written by treecut render\n");
  std::vector<RunSummary> runs;
  for (const std::string& name : a.scene.strategies) {
    const std::filesystem::path dir = a.scene.strategies.size() > 1 ? out / name : out;
    make_output_folder(dir);
    auto camera_at = [&](double t) {
      splat::Camera c = path.at(t);
      splat::fit_clip_planes(c, scene.center, scene.radius);
      return c;
    };
    splat::Camera cam = camera_at(0.0);
    StageOptions stage_options;
    stage_options.launch = a.sync ? Launch::Manual : Launch::Thread;
    // llvmpipe keeps both cores busy while it draws: the stage takes what is left.
    stage_options.priority = StagePriority::Idle;
    configure_stage(stage_options, a.scene);
    std::unique_ptr<Strategy> strategy = make_strategy(registry, name, a.scene.params);
    // The viewer's governor (--target-fps), fed the same way: frame time and
    // the splats that frame drew.
    std::optional<splat::FrameRateGovernor> governor;
    if (a.target_fps > 0.0) {
      governor = splat::FrameRateGovernor::for_strategy(*strategy, h.node_count());
    }
    // The scene's hierarchy itself (no copy): the renderer's vertex buffer is
    // of the hierarchy in the stage's lists, so it is never uploaded again.
    Controller controller(Model{scene.hierarchy, TreeCut::root_cut(h)}, std::move(strategy),
                          splat::view_snapshot(cam, size, settings.light), stage_options);
    splat::QueryExecutor queries;
    splat::RenderThreadFrame frame_loop(controller, renderer, &queries);
    const splat::CutBuffer& cut = frame_loop.cut();
    auto frame = [&](const splat::Camera& c) {
      const auto t0 = std::chrono::steady_clock::now();
      frame_loop.run_render_thread(c, settings, true);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      if (governor) {
        if (auto v = governor->update(ms, cut.size(), a.target_fps)) {
          controller.set_param(governor->param(), *v);
        }
      }
      // Synchronous mode: the stage's iteration runs here, outside the frame time.
      if (a.sync) controller.stage().step();
      return ms;
    };

    RunSummary run;
    run.strategy = name;
    for (int i = 0; i < a.warmup; ++i) frame(cam);
    for (int f = 0; f < a.frames; ++f) {
      const double t = a.frames > 1 ? path.duration() * f / (a.frames - 1) : 0.0;
      cam = camera_at(t);
      FrameRow row;
      row.frame = f;
      row.time_s = t;
      row.frame_ms = frame(cam);
      const StageCounters& counters = controller.stage().counters();
      row.cut_size = cut.size();
      row.points = cut.points();
      row.iteration_ms = double(counters.iteration_ns_last) * 1e-6;
      row.exchanges = counters.exchanges;
      row.iterations = counters.iterations;
      row.converged = counters.converged;
      if (!a.no_png || a.psnr) {
        const splat::Image lod = grab();
        if (!a.no_png) {
          char file[32];
          std::snprintf(file, sizeof file, "frame_%05d.png", f);
          splat::write_png(dir / file, lod);
        }
        if (a.psnr) {
          renderer.draw(full, cam, settings, true);
          row.psnr_db = splat::psnr(lod, grab());
        }
      }
      run.rows.push_back(row);
    }

    if (a.stability > 0) {
      // Static camera at the end of the path: let the strategy converge, then
      // count the pixels that still change from one frame to the next.
      for (int i = 0; i < 600 && !controller.stage().counters().converged; ++i) frame(cam);
      run.stability_converged = controller.stage().counters().converged;
      splat::Image previous = grab();
      double sum = 0.0, worst = 0.0;
      for (int i = 0; i < a.stability; ++i) {
        frame(cam);
        splat::Image current = grab();
        const double changed = splat::changed_fraction(previous, current);
        sum += changed;
        worst = std::max(worst, changed);
        previous = std::move(current);
      }
      run.stability_frames = a.stability;
      run.stability_changed = sum / a.stability;
      run.stability_max = worst;
      run.converged_cut = cut.size();
      renderer.draw(full, cam, settings, true);
      run.converged_psnr = splat::psnr(previous, grab());
    }

    write_csv(dir / "stats.csv", run.rows);
    write_file_atomically(dir / "summary.json", summary_json(run));
    std::printf(
        "%-13s %d frames: frame %.2f ms (median %.2f), cut %.0f nodes, iteration %.2f ms, "
        "%llu exchanges",
        name.c_str(), a.frames, mean_of(run.rows, &FrameRow::frame_ms), median_frame_ms(run.rows),
        std::accumulate(run.rows.begin(), run.rows.end(), 0.0,
                        [](double s, const FrameRow& r) { return s + double(r.cut_size); }) /
            double(run.rows.size()),
        mean_of(run.rows, &FrameRow::iteration_ms),
        static_cast<unsigned long long>(run.rows.back().exchanges));
    if (a.psnr) {
      const double mean = mean_psnr(run.rows);
      if (std::isfinite(mean))
        std::printf(", PSNR %.2f dB", mean);
      else
        std::printf(", PSNR %s dB (identical to full detail)", psnr_text(mean).c_str());
    }
    if (a.stability > 0) {
      std::printf(", stability %.5f changed (max %.5f)%s", run.stability_changed, run.stability_max,
                  run.stability_converged ? "" : " [not converged]");
    }
    std::printf("\n");
    // Only a strategy that posts GPU queries gets this line.
    if (const splat::QueryStats& q = queries.stats(); q.issued > 0 || q.answered > 0) {
      std::printf(
          "queries   %s: %llu issued, %llu answered (%llu occluded), %zu pending, "
          "%llu dropped, latency %.2f frames (max %llu), %.3f ms per frame\n",
          name.c_str(), static_cast<unsigned long long>(q.issued),
          static_cast<unsigned long long>(q.answered), static_cast<unsigned long long>(q.occluded),
          q.pending, static_cast<unsigned long long>(q.dropped), q.latency_frames_mean(),
          static_cast<unsigned long long>(q.latency_frames_max),
          double(q.cpu_ns_total) * 1e-6 / double(std::max<std::uint64_t>(controller.frame(), 1)));
    }
    // Fewer iterations than the path needed: say so (the frames lag or show the root).
    if (const std::string late =
            stage_shortfall(name, controller.stage().counters(), stage_options,
                            static_cast<int>(controller.stage().counters().frames));
        !late.empty()) {
      std::fflush(stdout);
      std::fprintf(stderr, "warning: %s\n", late.c_str());
    }
    if (governor) {
      std::printf("governor  %s = %.6g at the end, model %.2f ms + %.4g us/splat\n",
                  governor->param().c_str(), governor->value(), governor->fixed_ms(),
                  governor->per_splat_ms() * 1e3);
    }
    runs.push_back(std::move(run));
  }
  write_plot_svg(out / "plot.svg", runs, scene.label + ": frame time and cut size per strategy");
  std::printf("wrote     %s (stats.csv, summary.json, plot.svg%s)\n", out.string().c_str(),
              a.no_png ? "" : ", frame_*.png");
}

}  // namespace

void add_render_commands(CLI::App& app) {
  auto ra = std::make_shared<RenderArgs>();
  auto* render = app.add_subcommand(
      "render", "Render frames headless (OSMesa) along a camera path; write PNGs and statistics");
  add_scene_options(*render, ra->scene);
  // No CLI::ExistingFile on --path/--script: load_camera_path and
  // load_view_script say what a bad path is ("is a FIFO", "is a directory").
  render->add_option("--path", ra->path, "Camera path file (default: one orbit around the model)");
  render->add_option("-n,--frames", ra->frames, "Frames along the path")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  render->add_option("-o,--out", ra->out, "Output folder")->capture_default_str();
  render->add_option("--width", ra->width, "Frame width")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  render->add_option("--height", ra->height, "Frame height")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  render->add_option("--orbit-seconds", ra->orbit_seconds, "Duration of the default orbit")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  render->add_option("--warmup", ra->warmup, "Frames rendered at the first camera before recording")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  render->add_flag("--sync", ra->sync,
                   "Run the Feedback Stage synchronously, one iteration per frame (deterministic)");
  render->add_flag("--psnr", ra->psnr, "Also render full detail per frame and record the PSNR");
  render
      ->add_option("--stability", ra->stability,
                   "After the path: converge at the last camera, then measure this many frames "
                   "of temporal stability")
      ->check(CLI::Range(0, 100000));
  render->add_flag("--no-png", ra->no_png, "Write statistics only");
  render
      ->add_option("--target-fps", ra->target_fps,
                   "Adapt the strategy's budget to hold this frame rate, as the viewer (0 = off)")
      ->check(CLI::Range(0.0, 1000.0));
  render->callback([ra] { run_render(*ra); });

  auto va = std::make_shared<ViewArgs>();
  auto* view = app.add_subcommand("view", "Open a window on a model (GLFW, OpenGL 4.5 core)");
  add_scene_options(*view, va->scene);
  view->add_option("MORE", va->more_models, "Further models; O in the window opens the next");
  view->add_option("--width", va->width, "Window width")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  view->add_option("--height", va->height, "Window height")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  view->add_option("--path", va->path, "Replay this camera path");
  view->add_option("--script", va->script,
                   "Scripted run (see docs/camera-paths.md): replay, screenshot, exit");
  view->add_option("--screenshot-dir", va->screenshot_dir, "Where F12 / scripts save PNGs")
      ->capture_default_str();
  view->add_option("--target-fps", va->target_fps,
                   "Adapt the strategy's budget to hold this frame rate (0 = off)")
      ->check(CLI::Range(0.0, 1000.0));
  view->callback([va] {
    // The text inputs are checked before a window opens (and where there is
    // no display): a bad path or script is exit 2 with FILE:LINE.
    if (!va->path.empty()) (void)splat::load_camera_path(va->path);
    if (!va->script.empty()) {
      const StrategyRegistry registry = make_registry(va->scene);
      ScriptChecks checks{&registry, va->scene.strategies.empty() ? std::string("optimization")
                                                                  : va->scene.strategies.front()};
      (void)load_view_script(va->script, checks);
    }
    const int code = run_viewer(*va);
    if (code != 0) throw std::runtime_error("viewer failed");
  });
}

}  // namespace treecut::cli
