// treecut gen survey (survey_command.hpp)
#include "survey_command.hpp"

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>

#include "messages.hpp"
#include "output_checks.hpp"
#include "progress.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"
#include "treecut/parallel.hpp"
#include "treecut/tools/survey.hpp"

namespace treecut::cli {

namespace {

// A tile is generated whole in memory (about 50 bytes a point, per thread):
// past this a smaller --tile keeps the memory bounded.
constexpr std::uint64_t kMaxTilePoints = 20'000'000;

tools::SurveyOptions survey_options(const SurveyArgs& a, std::uint64_t points, std::uint64_t seed,
                                    const std::vector<double>& origin) {
  tools::SurveyOptions o;
  o.seed = seed;
  o.tile = a.tile;
  o.density = a.density;
  if (!a.area.empty()) {
    o.width = a.area[0] * 1000.0, o.height = a.area[1] * 1000.0;
    if (points != 0) o.density = double(points) / (o.width * o.height);
  } else if (points != 0) {
    o.width = o.height = std::sqrt(double(points) / o.density);
  }
  // On the millimetre grid the tiles' coordinates are written on.
  if (!origin.empty())
    o.origin = glm::round(glm::dvec3(origin[0], origin[1], origin[2]) * 1000.0) / 1000.0;
  return o;
}

}  // namespace

void generate_survey(const SurveyArgs& args, const std::string& out_arg, std::uint64_t points,
                     std::uint64_t seed, const std::vector<double>& origin) {
  const std::filesystem::path out =
      out_arg.empty() ? std::filesystem::path("assets/survey") : std::filesystem::path(out_arg);
  const tools::SurveyOptions o = survey_options(args, points, seed, origin);
  std::vector<tools::SurveyTile> tiles;
  try {
    tiles = tools::survey_tiles(o);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("gen survey: ") + e.what());
  }
  std::uint64_t total = 0;
  for (const tools::SurveyTile& t : tiles) {
    if (t.points > kMaxTilePoints)
      throw InputError("gen survey: " + std::to_string(t.points) + " points a tile; at most " +
                       std::to_string(kMaxTilePoints) + " (a smaller --tile)");
    total += t.points;
  }
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::symlink_status(out, ec)) &&
      !std::filesystem::is_directory(out, ec))
    throw InputError(quoted_name(out) + ": is not a folder (gen survey writes its tiles into one)");
  // Every tile is checked before the first is written: a refusal touches nothing.
  for (const tools::SurveyTile& t : tiles)
    check_replaceable_output(out / t.file_name, is_own_las, "a survey tile", "a LAS file");
  std::filesystem::create_directories(out, ec);
  if (ec) throw std::runtime_error(system_error_text(out, ec.value()));

  ProgressBar bar("survey");
  std::atomic<std::uint64_t> done{0};
  // One tile a thread at a time: the memory is a tile's per thread.
  WorkerPool pool(static_cast<unsigned>(std::min<std::size_t>(worker_count(), tiles.size())));
  pool.run(tiles.size(), 1, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) {
      const PointSet ps = tools::generate_survey_tile(o, tiles[i]);
      save_las(out / tiles[i].file_name, ps);
      bar.update("survey", static_cast<std::size_t>(done += ps.size()),
                 static_cast<std::size_t>(total));
    }
  });
  bar.finish();
  std::printf(
      "wrote %zu LAS %s into %s: %llu points, %.3g x %.3g km at %.3g points/m^2, "
      "EPSG:%d\n",
      tiles.size(), tiles.size() == 1 ? "tile" : "tiles", quoted_name(out).c_str(),
      static_cast<unsigned long long>(total), o.width / 1000.0, o.height / 1000.0, o.density,
      o.epsg);
}

}  // namespace treecut::cli
