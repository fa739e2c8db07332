// `treecut gen survey`: a generated flight's LAS tiles, written into a
// folder one tile at a time (tools/survey.hpp; issue 44, item 4).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace treecut::cli {

struct SurveyArgs {
  std::vector<double> area;  ///< --area W H, km (default: a square for -n, else 1 x 1)
  double density = 8.0;      ///< --density, returns per m²
  double tile = 500.0;       ///< --tile, metres
};

/// Writes the tiles into OUT (created if missing), replacing only tiles
/// treecut wrote; POINTS (0: not given) sets the area's size at the density,
/// or the density over a given --area. ORIGIN (empty: UTM 33N's 500000,
/// 5000000, 100): the south-west corner.
void generate_survey(const SurveyArgs& args, const std::string& out, std::uint64_t points,
                     std::uint64_t seed, const std::vector<double>& origin);

}  // namespace treecut::cli
