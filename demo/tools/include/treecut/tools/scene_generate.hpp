// Generated models a scene may name and the generated scenes (`treecut gen
// city-block | hall`): the "building" and "ground" models, the city block of
// tens of thousands of instanced buildings, the hall of instanced scans, and
// their walkthroughs. Procedural content of the tools layer: the core reads
// scene files (treecut/scene.hpp) and calls scene_generator() for their
// `generate` lines.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/point_set.hpp"
#include "treecut/scene.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut::tools {

/// The built-in kinds of a scene's `generate` lines: scene_generated_kinds()
/// made by generate_scene_model().
SceneGenerator scene_generator();

/// "sphere", "terrain", "city", "plant" (generate.hpp) and the scene parts
/// "building" and "ground".
std::vector<std::string> scene_generated_kinds();
/// Exactly POINTS points of KIND (one of scene_generated_kinds()); throws
/// InputError for another kind. Deterministic for a seed, parallel.
PointSet generate_scene_model(std::string_view kind, std::size_t points, std::uint64_t seed);

/// "building": a box building on the unit footprint [-0.5, 0.5]^2 from z = 0
/// to 1, walls and roof (no floor), the seed choosing a palette and whether it
/// has a set-back upper tier. Instances scale it per axis to their lot.
PointSet generate_building(std::size_t points, std::uint64_t seed);
/// "ground": the unit square [-0.5, 0.5]^2 at z = 0, normal +z (pavement).
PointSet generate_ground(std::size_t points, std::uint64_t seed);

// ---------------------------------------------------------------------------
// Generated scenes (`treecut gen city-block | hall`), in metres, z up.

/// A city of blocks of lots_x x lots_y lots between streets; each lot holds
/// one building, an instance of one of `models` building models, scaled per
/// axis to its footprint and height and turned by a multiple of 90 degrees;
/// each block stands on a ground tile (an instance of one ground model) that
/// reaches to the middle of the streets around it. Exactly `objects`
/// buildings (the last block may be partly filled), plus one tile per block.
struct CityBlockLayout {
  struct Building {
    std::uint32_t model = 0;  ///< 0 .. models - 1
    glm::vec2 centre{0.0f};
    glm::vec3 size{0.0f};  ///< model-space scale: footprint x, y (before the turn), height
    int quarter_turns = 0;
  };
  int lots_x = 8, lots_y = 4;
  float lot_w = 15.0f, lot_d = 20.0f;  ///< lot size along x and y
  float street = 16.0f;                ///< street width
  int blocks_x = 0, blocks_y = 0;      ///< the grid of blocks (blocks_x * blocks_y >= used)
  int blocks = 0;                      ///< blocks with at least one building
  std::uint32_t models = 4;
  glm::vec2 origin{0.0f};  ///< corner of block (0, 0) (the grid is centred on 0)
  std::vector<Building> buildings;
  [[nodiscard]] float pitch_x() const { return lots_x * lot_w + street; }
  [[nodiscard]] float pitch_y() const { return lots_y * lot_d + street; }
};
CityBlockLayout city_block_layout(std::size_t objects, std::uint64_t seed);

/// The scene file of a city block: `generate` lines for the building and
/// ground models (POINTS each) and an object line per building and tile.
std::string format_city_block_scene(const CityBlockLayout& layout, std::uint64_t seed,
                                    std::size_t points);
/// Its walkthrough: the overview, down into the street west of the centre,
/// a walk three blocks east, two north and back west at 1.7 m, and up.
std::vector<WalkKey> city_block_walkthrough(const CityBlockLayout& layout);

/// A hall of rows x cols plinth places on a floor; in each an instance of one
/// of the sources, stood upright (its detected up axis turned to +z), scaled
/// to a height of 1.4 .. 2.2 m and turned at random about z.
struct HallSource {
  std::filesystem::path path;  ///< as written in the scene (relative to it, or absolute)
  glm::vec3 up{0.0f, 0.0f, 1.0f};
  glm::vec3 box_min{0.0f}, box_max{0.0f};  ///< model-space bounds
};
struct HallLayout {
  struct Copy {
    std::uint32_t source = 0;
    glm::vec2 centre{0.0f};
    float height = 0.0f;  ///< metres
    float turn_deg = 0.0f;
  };
  int rows = 0, cols = 0;
  float spacing = 4.0f;  ///< between neighbouring places
  glm::vec2 lo{0.0f}, hi{0.0f};
  std::vector<Copy> copies;
};
HallLayout hall_layout(std::size_t objects, std::size_t sources, std::uint64_t seed);
std::string format_hall_scene(const HallLayout& layout, const std::vector<HallSource>& sources,
                              std::uint64_t seed, std::size_t floor_points);
/// Its walkthrough: the overview, down into the aisle at the hall's south
/// side, a walk east along it, north and back west at 1.6 m, and up.
std::vector<WalkKey> hall_walkthrough(const HallLayout& layout);

}  // namespace treecut::tools
