// treecut bench occlusion, the HLOD table (Charalambos et al. 2007,
// ../shared/papers/hoq-driven-hlod-refinement.txt, table 1): Bool, SW(B),
// Simp(B), Coh(B) in-frame (strategies/hlod_traversal.hpp), Coh(B) made
// for a GPU's latency ("Coh(B) tolerant"), and the `hoq`
// stage strategy through the frame layer (as `treecut render --sync`), on the
// walkthrough's cameras; the luminance PSNR of Coh(B) and hoq against Bool;
// per-frame CSV for tests/bench/occlusion_plot.py.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "treecut/culling/gpu_latency.hpp"
#include "treecut/culling/hlod_blocks.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/occlusion_device_gl.hpp"
#include "treecut/splat/renderer.hpp"

namespace treecut::cli {

struct HlodBenchInput {
  std::shared_ptr<const Hierarchy> hierarchy;
  const culling::HlodBlocks* blocks = nullptr;
  splat::Renderer* renderer = nullptr;
  splat::GlOcclusionDevice* device = nullptr;
  std::vector<splat::Camera> cameras;
  splat::RenderSettings settings;
  glm::ivec2 size{1280, 720};
  float tau = 1.0f;
  int psnr_frames = 20;
  /// The GPU-latency model of every method (the executor's in frames).
  culling::GpuLatency latency;
  /// Non-empty: the per-frame CSV goes to this file (checked by
  /// check_hlod_csv before any work).
  std::filesystem::path csv;
};

/// The CSV the bench writes into DIR for a scene: DIR/occlusion_STEM.csv.
[[nodiscard]] std::filesystem::path hlod_csv_path(const std::filesystem::path& dir,
                                                  const std::string& scene);
/// Refuses (InputError naming the file) a CSV target that exists and is not
/// an earlier run's CSV (its first line is the bench's header), or a folder
/// that is not a folder. Creates nothing.
void check_hlod_csv(const std::filesystem::path& csv);

/// Runs the methods frame by frame in turns and prints the table and the PSNR.
void run_hlod_table(const HlodBenchInput& in);

}  // namespace treecut::cli
