// A survey like an airborne laser scanner's flight (issue 44): an area of
// terrain with roads, buildings and trees, cut into square tiles of LAS, as a
// city's or a county's flight is delivered. Unlike `gen terrain`, whose
// points repeat positions at large counts (a 2 m patch at 1 mm), every point
// here is a pulse's return at a random place on a millimetre grid over
// kilometres, so positions are distinct and the data has the statistics a
// build meets in the field: classes (ground 2, road 11, vegetation 5,
// building 6), one to three returns under trees, intensity by surface,
// scan angle and GPS time of parallel flight lines (point source ids),
// colour from an orthophoto-like palette.
//
// Every tile is a pure function of (options, tile): tiles are generated
// independently, in any order, in memory proportional to one tile, and the
// terrain, buildings and trees continue across tile borders.
#pragma once

#include <cstdint>
#include <glm/ext/vector_double2.hpp>
#include <glm/ext/vector_double3.hpp>
#include <string>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::tools {

struct SurveyOptions {
  double width = 1000.0, height = 1000.0;  ///< the area east and north, metres
  double density = 8.0;                    ///< returns per m², over the whole area
  double tile = 500.0;                     ///< tile edge, metres
  /// The south-west corner in map coordinates (UTM zone 33 north, metres).
  glm::dvec3 origin{500000.0, 5000000.0, 100.0};
  std::uint64_t seed = 1;
  int epsg = 32633;  ///< the projected coordinate system named in each tile
};

/// One tile: its place in the grid, its area (local metres from the
/// south-west corner) and how many points it holds.
struct SurveyTile {
  int column = 0, row = 0;
  glm::dvec2 lo{0.0}, hi{0.0};
  std::uint64_t points = 0;
  /// "tile_<easting km>_<northing km>.las"-like file name (easting and
  /// northing of its south-west corner in metres).
  std::string file_name;
};

/// The tiles of the area, row by row from the south-west; their points add
/// up to round(density * width * height), shared by area. std::invalid_argument
/// for sizes that are not positive and finite, or past 2^40 points.
std::vector<SurveyTile> survey_tiles(const SurveyOptions& options);

/// The points of one tile, with their LAS fields as attributes and the
/// coordinate system's GeoTIFF keys: what `gen survey` writes with
/// save_las. Positions on a 1 mm grid.
PointSet generate_survey_tile(const SurveyOptions& options, const SurveyTile& tile);

/// The GeoTIFF key directory (LAS record 34735) naming projected EPSG CODE
/// in metres.
std::string geotiff_keys_for_epsg(int code);

}  // namespace treecut::tools
