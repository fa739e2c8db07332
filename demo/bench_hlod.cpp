// treecut bench occlusion, the HLOD table: J. P. Charalambos, J. Bittner,
// M. Wimmer, E. Romero, "Optimized HLOD Refinement Driven by Hardware
// Occlusion Queries", ISVC 2007 (../shared/papers/hoq-driven-hlod-refinement.txt,
// table 1 and the PSNR of section 5.2), on the walkthrough bench occlusion
// runs (docs/occlusion.md, "HLOD in-frame").
#include "bench_hlod.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "bench_common.hpp"
#include "render_reports.hpp"
#include "treecut/controller.hpp"
#include "treecut/culling/hlod_traversal.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/model.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/query_executor.hpp"
#include "treecut/strategies/hoq.hpp"

namespace treecut::cli {

namespace {

constexpr const char* kCsvHeader =
    "frame,method,frame_ms,drawn_blocks,splats,rarn,delayed,delays,queries,wait_ms,psnr_luma_db,"
    "blocking_reads,late_refined";

struct Row {
  double frame_ms = 0.0;
  double drawn = 0, splats = 0, rarn = 0, delayed = 0, delayed_all = 0, queries = 0, wait_ms = 0;
  // Reads that waited, and drawn blocks refined a frame late (their answer
  // carried: Coh(B) tolerant; the stage strategy's late refinements).
  double blocking = 0, late = 0;
  // D by cause and the stops drawn although hidden (the analysis of DN / SW(B)).
  double d_shift_up = 0, d_new = 0, d_hidden = 0, stopped_hidden = 0;
  double psnr = std::numeric_limits<double>::quiet_NaN();
};

struct Method {
  std::string name;
  std::vector<Row> rows;
};

double mean_of(const std::vector<Row>& rows, double Row::*field) {
  double sum = 0.0;
  for (const Row& r : rows) sum += r.*field;
  return rows.empty() ? 0.0 : sum / double(rows.size());
}

double median_of(const std::vector<Row>& rows, double Row::*field) {
  std::vector<double> v;
  for (const Row& r : rows) v.push_back(r.*field);
  return v.empty() ? 0.0 : median(std::move(v));
}

// The methods' rows, in this order: the four in-frame traversals, Coh(B)
// made for a GPU's latency (HlodOptions::carry_answers and
// assume_new_visible), then the stage strategy.
constexpr std::size_t kBool = 0, kSwB = 1, kSimp = 2, kCoh = 3, kCohCarried = 4, kHoq = 5;

// One frame of an in-frame traversal (Bool, SW(B), Simp(B), Coh(B)) on the
// occlusion device.
Row traversal_row(culling::HlodTraversal& traversal, culling::LatentOcclusionDevice& device,
                  const splat::Camera& cam, const HlodBenchInput& in) {
  Row row;
  in.device->set_view_render_thread(cam, in.settings);
  const culling::HlodFrameStats s = traversal.frame_render_thread(device, cam.view(in.size), true);
  row.frame_ms = s.frame_ms;
  row.drawn = double(s.drawn);
  row.splats = double(s.splats);
  row.rarn = double(s.rarn);
  row.delayed = double(s.delayed_drawn);
  row.delayed_all = double(s.delayed);
  row.queries = double(s.queries);
  row.wait_ms = s.wait_ms;
  row.d_shift_up = double(s.delayed_drawn_shift_up);
  row.d_new = double(s.delayed_drawn_new);
  row.d_hidden = double(s.delayed_drawn_hidden);
  row.stopped_hidden = double(s.stopped_hidden);
  row.blocking = double(s.blocking_reads);
  row.late = double(s.late_refined);
  return row;
}

// One frame of the stage strategy `hoq` through the frame layer, as
// `treecut render --sync`: the frame timed, then the stage's iteration.
Row stage_hoq_row(splat::RenderThreadFrame& frame_loop, Controller& controller,
                  const strategies::HoqStrategy& hoq, const splat::QueryExecutor& queries,
                  const splat::Camera& cam, const splat::RenderSettings& settings) {
  Row row;
  const std::uint64_t issued = queries.stats().issued;
  const auto t0 = std::chrono::steady_clock::now();
  const splat::FrameResult fr = frame_loop.run_render_thread(cam, settings, true);
  row.frame_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  controller.stage().step();  // outside the frame time, as render --sync
  const strategies::HoqCounters& c = hoq.last();
  row.drawn = double(c.drawn);
  row.splats = double(fr.stats.splats);
  row.rarn = double(c.rarn);
  // The stage form's D: blocks whose decision waits for an answer (drawn
  // at their level meanwhile, or shift-up candidates).
  row.delayed = double(c.delayed);
  row.delayed_all = double(c.delayed);
  row.queries = double(queries.stats().issued - issued);
  row.late = double(c.late_refined);
  return row;
}

// Per frame of the path, 1 where the PSNR is measured: PSNR_FRAMES evenly
// spread over its N frames.
std::vector<std::uint8_t> psnr_frame_marks(std::size_t n, int psnr_frames) {
  std::vector<std::uint8_t> psnr_frame(n, 0);
  const std::size_t k = std::min<std::size_t>(std::max(psnr_frames, 0), n);
  for (std::size_t i = 0; i < k; ++i) psnr_frame[k == 1 ? 0 : i * (n - 1) / (k - 1)] = 1;
  return psnr_frame;
}

// The paper's table 1 (one line per method) and Coh(B)'s analysis line.
void print_table(const std::vector<Method>& methods, float tau) {
  const double coh_ms = mean_of(methods[kCoh].rows, &Row::frame_ms);
  std::printf(
      "\nHLOD refinement (Charalambos et al. 2007), tau = %.2f px, s = t = 0.5; DN = HLOD blocks "
      "drawn; speed-up = method's frame ms / Coh(B)'s\n",
      double(tau));
  std::printf(
      "| method | DN | splats | RARN | late refined | D | D / DN | all delays | queries | blocking "
      "reads | wait ms | frame ms (mean) | frame ms (median) | speed-up of Coh(B) |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const Method& m : methods) {
    const double dn = mean_of(m.rows, &Row::drawn);
    const double d = mean_of(m.rows, &Row::delayed);
    const double ms = mean_of(m.rows, &Row::frame_ms);
    std::printf(
        "| %s | %.1f | %.0f | %.2f | %.2f | %.2f | %.2f%% | %.2f | %.1f | %.2f | %.3f | %.2f | "
        "%.2f | %.2f |\n",
        m.name.c_str(), dn, mean_of(m.rows, &Row::splats), mean_of(m.rows, &Row::rarn),
        mean_of(m.rows, &Row::late), d, dn > 0 ? 100.0 * d / dn : 0.0,
        mean_of(m.rows, &Row::delayed_all), mean_of(m.rows, &Row::queries),
        mean_of(m.rows, &Row::blocking), mean_of(m.rows, &Row::wait_ms), ms,
        median_of(m.rows, &Row::frame_ms), coh_ms > 0 ? ms / coh_ms : 0.0);
  }
  const std::vector<Row>& c = methods[kCoh].rows;
  std::printf(
      "Coh(B) per frame: D by cause: shift-up %.2f, new to the traversal %.2f, hidden last "
      "frame %.2f; stops drawn and found hidden %.2f (Simp(B) %.2f); splats per drawn block: "
      "Bool %.0f, SW(B) %.0f, Coh(B) %.0f\n",
      mean_of(c, &Row::d_shift_up), mean_of(c, &Row::d_new), mean_of(c, &Row::d_hidden),
      mean_of(c, &Row::stopped_hidden), mean_of(methods[kSimp].rows, &Row::stopped_hidden),
      mean_of(methods[kBool].rows, &Row::splats) /
          std::max(mean_of(methods[kBool].rows, &Row::drawn), 1e-9),
      mean_of(methods[kSwB].rows, &Row::splats) /
          std::max(mean_of(methods[kSwB].rows, &Row::drawn), 1e-9),
      mean_of(c, &Row::splats) / std::max(mean_of(c, &Row::drawn), 1e-9));
}

// The PSNR (section 5.2) of Coh(B) and the stage strategy against Bool's images.
void print_psnr(const std::vector<Method>& methods) {
  for (const std::size_t m : {kCoh, kCohCarried, kHoq}) {
    double sum = 0.0, low = std::numeric_limits<double>::infinity();
    int count = 0, capped = 0;
    for (const Row& r : methods[m].rows) {
      if (!std::isfinite(r.psnr)) continue;
      sum += r.psnr;
      low = std::min(low, r.psnr);
      ++count;
      capped += r.psnr >= kLumaPsnrCap ? 1 : 0;
    }
    std::printf(
        "PSNR (luma) of %s against Bool on %d frames: mean %.2f dB, min %.2f dB (%d frames "
        "identical, counted as %.0f dB)\n",
        methods[m].name.c_str(), count, count > 0 ? sum / count : 0.0, count > 0 ? low : 0.0,
        capped, kLumaPsnrCap);
  }
}

// The per-frame CSV (kCsvHeader) of the path's N frames, every method a line.
void write_csv(const std::filesystem::path& csv, const std::vector<Method>& methods,
               std::size_t n) {
  std::ostringstream o;
  o << kCsvHeader << "\n";
  for (std::size_t f = 0; f < n; ++f) {
    for (const Method& m : methods) {
      const Row& r = m.rows[f];
      char line[256];
      std::snprintf(line, sizeof line, "%zu,%s,%.4f,%.0f,%.0f,%.0f,%.0f,%.0f,%.0f,%.4f,", f,
                    m.name.c_str(), r.frame_ms, r.drawn, r.splats, r.rarn, r.delayed, r.delayed_all,
                    r.queries, r.wait_ms);
      o << line;
      if (std::isfinite(r.psnr)) o << r.psnr;
      o << "," << r.blocking << "," << r.late << "\n";
    }
  }
  write_bench_csv(csv, o.str());
}

}  // namespace

std::filesystem::path hlod_csv_path(const std::filesystem::path& dir, const std::string& scene) {
  return dir / ("occlusion_" + std::filesystem::path(scene).stem().string() + ".csv");
}

void check_hlod_csv(const std::filesystem::path& csv) {
  check_bench_csv(csv, kCsvHeader, "bench occlusion");
}

void run_hlod_table(const HlodBenchInput& in) {
  using culling::HlodMode;
  const Hierarchy& h = *in.hierarchy;
  splat::Renderer& renderer = *in.renderer;
  const glm::ivec2 size = in.size;
  const HlodMode modes[] = {HlodMode::Bool, HlodMode::SwB, HlodMode::SimpB, HlodMode::CohB};
  std::vector<Method> methods;
  std::vector<culling::HlodTraversal> traversals;
  // Each method its own latency model (its frames are its own).
  std::vector<culling::LatentOcclusionDevice> latent;
  for (const HlodMode m : modes) {
    culling::HlodOptions o;
    o.mode = m;
    o.tau = in.tau;
    traversals.emplace_back(h, *in.blocks, o);
    methods.push_back({std::string(culling::hlod_mode_name(m)), {}});
  }
  culling::HlodOptions carried;
  carried.tau = in.tau;
  carried.carry_answers = true;
  carried.assume_new_visible = true;
  traversals.emplace_back(h, *in.blocks, carried);
  methods.push_back({"Coh(B) tolerant", {}});
  for (std::size_t m = 0; m < traversals.size(); ++m) latent.emplace_back(*in.device, in.latency);
  methods.push_back({"hoq (stage)", {}});  // no comma: a CSV field

  // The stage strategy through the frame layer, as `treecut render --sync`:
  // its queries go through the executor, its iteration runs after the frame.
  auto hoq_owned = std::make_unique<strategies::HoqStrategy>();
  strategies::HoqStrategy* hoq = hoq_owned.get();
  hoq->set_param("theta", in.tau);
  StageOptions stage_options;
  stage_options.launch = Launch::Manual;
  Controller controller(Model{in.hierarchy, TreeCut::root_cut(h)}, std::move(hoq_owned),
                        splat::view_snapshot(in.cameras.front(), size, in.settings.light),
                        stage_options);
  splat::QueryExecutorOptions executor_options;
  executor_options.min_answer_frames = std::max<std::uint64_t>(1, in.latency.frames);
  splat::QueryExecutor queries(executor_options);
  splat::RenderThreadFrame frame_loop(controller, renderer, &queries);

  auto run = [&](std::size_t m, const splat::Camera& cam) {
    if (m == kHoq) return stage_hoq_row(frame_loop, controller, *hoq, queries, cam, in.settings);
    return traversal_row(traversals[m], latent[m], cam, in);
  };
  auto grab = [&] { return splat::Image{size.x, size.y, renderer.read_pixels()}; };

  // Untimed frames at the first camera: caches warm, and every method starts
  // the path with previous frames (the stage strategy with its answers).
  constexpr int kWarmup = 5;
  for (int i = 0; i < kWarmup; ++i) {
    for (std::size_t m = 0; m < methods.size(); ++m) (void)run(m, in.cameras.front());
  }
  const std::size_t n = in.cameras.size();
  const std::vector<std::uint8_t> psnr_frame = psnr_frame_marks(n, in.psnr_frames);
  for (std::size_t f = 0; f < n; ++f) {
    splat::Image reference;
    for (std::size_t m = 0; m < methods.size(); ++m) {
      Row row = run(m, in.cameras[f]);
      if (psnr_frame[f] != 0 && (m == kBool || m == kCoh || m == kCohCarried || m == kHoq)) {
        splat::Image image = grab();
        if (m == kBool) {
          reference = std::move(image);
        } else {
          row.psnr = luma_psnr(image, reference);
        }
      }
      methods[m].rows.push_back(row);
    }
  }

  for (std::size_t m = 0; m < traversals.size(); ++m)
    traversals[m].release_render_thread(latent[m]);
  print_table(methods, in.tau);
  print_psnr(methods);
  std::fflush(stdout);
  if (!in.csv.empty()) write_csv(in.csv, methods, n);
}

}  // namespace treecut::cli
