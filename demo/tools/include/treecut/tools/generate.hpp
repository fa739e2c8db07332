// Procedural models the project owns (no external data needed): used by
// `treecut gen`, the default model of the viewer, tests and benchmarks.
#pragma once

#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::tools {

enum class ModelKind {
  Sphere,   ///< points on a unit sphere, normals outward, colored by latitude
  Terrain,  ///< a noisy height field (fractal value noise), normals from the field
  City,     ///< streets and blocks of box buildings on a ground plane: heavy occlusion
  Field,    ///< copies of a scanned model on a ground plane (needs a source: generate_field)
  Plant,    ///< an industrial plant: tanks, pipe racks, risers on a ground plane
};

/// "sphere", "terrain", "city", "field", "plant" -> kind; throws InputError
/// for anything else.
ModelKind parse_model_kind(std::string_view name);
std::vector<std::string> model_kind_names();

/// Generates exactly `points` points,
/// with exact normals and colors (radii and curvature come from
/// complete_attributes, as for any point cloud); deterministic for a seed. Parallel.
/// Field needs a source model: InputError here (use generate_field).
PointSet generate_model(ModelKind kind, std::size_t points, std::uint64_t seed = 1);

/// What a survey file of the generated model carries (`gen -o X.las`): an
/// intensity from each point's brightness (0-65535, as a scanner's return
/// strength reads) and, for the city, the ASPRS classification of its
/// surfaces (2 ground, 6 building). Deterministic.
void add_survey_attributes(PointSet& points, ModelKind kind);

// ---------------------------------------------------------------------------
// Scenes with depth complexity (demo/tools/src/generate_{city,plant,field}.cpp; docs/scenes.md).
// All three stand on the ground square [-1, 1]^2 at z = 0, z up; think of one
// unit as 500 m for the city. Points are spread uniformly by area over the
// visible surfaces (ground minus footprints, walls, roofs, pipes, caps), so
// the spacing is sqrt(area / points). The layouts are pure functions of the
// seed, so tests and the walkthroughs see exactly what was sampled.

/// The city: blocks x blocks blocks of pitch block_pitch separated by streets
/// of street_width centred on x, y = -1 + k * block_pitch; each block (unless
/// a park, about one in twelve) holds 1..2 x 1..2 lots with a building each,
/// placed at random in its lot (set back from the street by `setback`, alleys
/// between). Heights 0.012 .. ~0.38, taller downtown. Surface area at seed 1:
/// 9.0 units^2 (spacing 0.0030 per million points). The walkthrough's eye is
/// at 0.008 (4 m).
struct CityLayout {
  struct Building {
    glm::vec3 lo, hi;  ///< box, lo.z = 0
    int style = 0;     ///< facade palette 0..3
  };
  int blocks = 8;
  float block_pitch = 0.25f;
  float street_width = 0.045f;
  float setback = 0.004f;
  float alley = 0.006f;
  std::vector<bool> park;               ///< per block, row-major from (-1, -1)
  std::vector<Building> buildings;      ///< ordered by block
  std::vector<std::uint32_t> block_of;  ///< the block of each building
};
CityLayout city_layout(std::uint64_t seed);
PointSet generate_city(std::size_t points, std::uint64_t seed);

/// The plant: cells x cells cells of cell_pitch with aisles of aisle_width
/// centred on x, y = -1 + k * cell_pitch; tanks (vertical cylinders with a top
/// cap) in the cells, a low feeder pipe from each tank to its aisle, pipe
/// racks (horizontal pipes, radius 0.004..0.011) along every inner aisle at
/// 0.045..0.08 (along x) and 0.085..0.12 (along y) but off its centre line,
/// and a riser at each inner crossing. No cylinder reaches the centre line of
/// an aisle below z = 0.03. Surface area at seed 1: 13.7 units^2 (spacing
/// 0.0037 per million points); the walkthrough's eye is at 0.010.
struct PlantLayout {
  struct Cylinder {
    glm::vec3 base;  ///< centre of the bottom end
    glm::vec3 axis;  ///< unit: +x, +y or +z
    float radius = 0, length = 0;
    bool tank = false;  ///< a tank: has a top cap, its footprint hides the ground
    std::uint32_t id = 0;
  };
  int cells = 6;
  float cell_pitch = 2.0f / 6.0f;
  float aisle_width = 0.07f;
  float margin = 0.01f;
  std::vector<Cylinder> cylinders;
};
PlantLayout plant_layout(std::uint64_t seed);
PointSet generate_plant(std::size_t points, std::uint64_t seed);

/// The field: cells x cells cells of cell_pitch; in each (but about one in
/// ten, a clearing) a copy of the source model standing on the ground, turned
/// by `angle` about z and scaled so its horizontal radius is `radius`, placed
/// so that lanes of lane_width along the cell borders stay free. Area: the
/// ground (4) plus the unit source's area times the sum of radius^2. The
/// walkthrough's eye is at 0.025.
struct FieldLayout {
  struct Copy {
    glm::vec2 centre{0.0f};
    float angle = 0.0f;   ///< radians about +z
    float radius = 0.0f;  ///< horizontal radius = scale of the unit source
  };
  int cells = 10;
  float cell_pitch = 0.2f;
  float lane_width = 0.04f;
  float min_radius = 0.055f, max_radius = 0.08f;
  std::vector<Copy> copies;
};
FieldLayout field_layout(std::uint64_t seed);

/// The source of a field, normalized: turned so its detected up axis is +z,
/// standing on z = 0, centred, unit horizontal radius; with the cumulative
/// areas that make the sampling uniform by area (of its faces, or of its
/// splats for a point cloud).
struct FieldSource {
  PointSet points;            ///< positions, normals, colors, triangles
  std::vector<double> area;   ///< cumulative area per face (or per point)
  std::vector<float> jitter;  ///< tangential jitter radius per point (point clouds)
  double unit_area = 0.0;     ///< the unit copy's surface area
};
/// `source` needs normals (and radii without faces): complete_attributes.
FieldSource prepare_field_source(const PointSet& source);
PointSet generate_field(const FieldSource& source, std::size_t points, std::uint64_t seed);

/// A camera key of a walkthrough (the campath format's fields).
struct WalkKey {
  double time = 0.0;
  glm::vec3 eye{0.0f}, target{0.0f}, up{0.0f, 0.0f, 1.0f};
  float fov_deg = 50.0f;
};
/// The walkthrough of a scene: an overview from above (an arc
/// about the scene), a move to above the scene's west edge, a vertical descent
/// to eye level on a street or aisle, a walk along it east, north and back
/// west (with the view looking ahead along the route), the ascent and the
/// overview again. Keys every 0.1 s. The routes follow the lanes that every
/// seed keeps free (streets, aisles, the field's lanes), so one path serves
/// every seed. City, Field or Plant; InputError otherwise.
std::vector<WalkKey> scene_walkthrough(ModelKind kind);
/// Eye height of the walkthrough at street level, in model units.
float walk_eye_height(ModelKind kind);

/// The walkthrough of a scene of objects on the ground plane (z up) within
/// [lo, hi] in x and y and below z = top (the generated scenes of scene.hpp):
/// an overview arc about the scene, a move to above the start of ROUTE, a
/// vertical descent to EYE height, the walk along the ROUTE polyline (at
/// least two points, in lanes that stay free) at SPEED units per second
/// looking AHEAD units along it, the ascent and the overview again. Keys
/// every 0.1 s. InputError for a route of fewer than two points or an empty
/// extent.
std::vector<WalkKey> route_walkthrough(glm::vec2 lo, glm::vec2 hi, float top,
                                       const std::vector<glm::vec2>& route, float eye, float speed,
                                       float ahead);

}  // namespace treecut::tools
