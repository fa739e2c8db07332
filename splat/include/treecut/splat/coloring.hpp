// Colouring a model by what its points carry (issue 29, item 3): the file's
// RGB, the elevation, or any attribute (Hierarchy::attributes) through a
// colour map; and hiding classes. NodeColoring gives any node its colour;
// color_nodes computes one per node on the CPU, which
// Renderer::set_node_colors puts in place of the model's own, and a model
// drawn from its pages has its nodes coloured as their pages go up to the
// GPU (Renderer::set_node_coloring, issue 45). No GL here, so any thread
// may call it.
//
// Maps: viridis (perceptually uniform, readable in grey and by the
// colour-blind; van der Walt and Smith, matplotlib 2015), grey, and for
// categories the ASPRS classification palette (LAS 1.4 R15, table 17's
// classes 0-18, coloured as LiDAR viewers do: ground brown, vegetation
// greens, buildings red, water blue) or ten distinct colours for other
// categories.
#pragma once

#include <cstdint>
#include <glm/gtc/type_precision.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/hierarchy.hpp"

namespace treecut::splat {

enum class ColorMap : std::uint8_t { automatic, viridis, grey, classes };

/// "auto", "viridis", "grey", "classes".
std::string_view color_map_name(ColorMap map);
/// Inverse of color_map_name (also "gray"); throws InputError.
ColorMap parse_color_map(std::string_view name);

struct ColorBy {
  /// "rgb" (the file's colours, grey without), "elevation" (along `up`), the
  /// name of an attribute, or "auto" (resolve_auto_color: rgb where the file
  /// has usable colours).
  std::string source = "rgb";
  /// automatic: classes for a category, viridis for the rest.
  ColorMap map = ColorMap::automatic;
  /// The file's values at the ends of a continuous map; default: the 2nd
  /// and 98th percentiles of the points (outliers do not wash it out).
  std::optional<double> low, high;
  /// Classes (of the "classification" attribute) to show, or with a leading
  /// '-' to hide: "2,6" shows ground and buildings only, "-7,-18" hides
  /// noise. Empty: all. Parsed by parse_class_filter.
  std::vector<int> show_classes, hide_classes;
};

/// "2,6" -> show {2, 6}; "-7,-18" -> hide {7, 18}; a mix is an InputError,
/// as is anything but whole numbers 0-255.
void parse_class_filter(std::string_view text, ColorBy& by);

/// Whether BY's class filter hides class VALUE (-1: no value; hidden only
/// when BY lists classes to show).
[[nodiscard]] bool class_hidden(const ColorBy& by, int value);

/// What the colours mean, for a HUD or a report.
struct Legend {
  std::string title;  ///< "intensity", "elevation (m)", "classification"
  ColorMap map = ColorMap::viridis;
  bool continuous = true;
  double low = 0.0, high = 0.0;  ///< continuous: the file's values at the ends
  struct Entry {
    double value = 0.0;
    std::string label;  ///< "2 ground" or "3"
    glm::u8vec4 color{0};
    double share = 0.0;  ///< of the points, 0..1; NaN: not counted (a paged model's)
    bool hidden = false;
  };
  std::vector<Entry> entries;  ///< categories, by value (at most 32)
};

struct Coloring {
  std::vector<glm::u8vec4> colors;  ///< one per node; alpha 0: hidden
  Legend legend;
  std::size_t hidden_nodes = 0;
};

/// BY with an "auto" source made what it means for H (issue 43, item 11):
/// the file's RGB where its points' colours differ; else, the RGB absent or
/// the same at every point (a file of all-zero colours drew 83 % near-black),
/// the intensity where it varies, else the elevation. *NOTE (if given) says
/// which and why, once ("no usable RGB (every point 0 0 0): coloured by
/// intensity"); empty when RGB is used. Any other source is returned as it is.
/// The colours looked at are those of LEAVES (a paged model's: the leaves of
/// its known part, treecut::sample_leaves), or of every leaf of H when empty.
ColorBy resolve_auto_color(const Hierarchy& h, ColorBy by, std::string* note = nullptr,
                           std::span<const NodeId> leaves = {});

/// Throws what color_nodes would for H and BY (an attribute H lacks, a
/// class filter without classification), before any work.
void check_color_by(const Hierarchy& h, const ColorBy& by);

/// BY for one node of H at a time: what color_nodes gives every node, with
/// no colour a node kept (a model drawn from its pages colours a page's
/// nodes when the page goes up). SAMPLE: leaves of H. Unless BY gives them,
/// a continuous map's ends are the 2nd and 98th percentiles of SAMPLE's
/// values, and a legend's categories are counted over every leaf of H.
/// With PARTIAL, H is known only in part (a model drawn from its pages:
/// SAMPLE is the leaves of its root page, coarse nodes whose values are
/// their points' means or modes): the ends are the points' extremes (the
/// attribute's, the bounds' along UP), the categories those SAMPLE has,
/// not counted (share NaN). Throws InputError as check_color_by does. H
/// must outlive it.
class NodeColoring {
 public:
  NodeColoring(const Hierarchy& h, const ColorBy& by, glm::vec3 up, std::span<const NodeId> sample,
               bool partial);
  [[nodiscard]] glm::u8vec4 operator()(NodeId n) const;
  /// Whether BY's class filter hides node N (alpha 0).
  [[nodiscard]] bool hidden(NodeId n) const;
  [[nodiscard]] const Legend& legend() const { return legend_; }

 private:
  enum class Kind : std::uint8_t { own, elevation, measure, category };
  [[nodiscard]] bool filtered() const {
    return !by_.show_classes.empty() || !by_.hide_classes.empty();
  }
  [[nodiscard]] glm::u8vec4 category(float v) const;
  void count_categories(std::span<const NodeId> sample, bool partial);

  const Hierarchy* h_;
  ColorBy by_;
  Kind kind_ = Kind::own;
  glm::vec3 up_{0.0f};
  const NodeAttribute* source_ = nullptr;          // measure, category
  const NodeAttribute* classification_ = nullptr;  // a class filter's
  double low_ = 0.0, scale_ = 1.0;                 // continuous: (x - low) * scale in [0, 1]
  bool asprs_ = false;                             // category: the ASPRS palette
  Legend legend_;
};

/// Colours every node of H by BY (UP: the elevation's direction, unit):
/// NodeColoring over H held whole. Throws InputError naming what the model
/// has for an unknown attribute or for a class filter without a
/// "classification" attribute.
Coloring color_nodes(const Hierarchy& h, const ColorBy& by, glm::vec3 up);

/// The map at T in [0, 1] (continuous maps).
glm::u8vec4 map_color(ColorMap map, float t);
/// The colour of category VALUE: ASPRS colours when ASPRS, else ten
/// distinct colours in turn.
glm::u8vec4 category_color(int value, bool asprs);
/// ASPRS class names ("ground", "high vegetation"); empty past 18.
std::string_view asprs_class_name(int value);

}  // namespace treecut::splat
