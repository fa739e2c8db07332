// The parts of PLY import, in the order load_ply (ply_load.cpp) runs them:
//   ply_elements.cpp  what the file holds: the vertex properties by meaning,
//                     the elements used and ignored, the warnings naming them;
//   ply_plan.cpp      the way to OpenMesh: which layouts its reader decodes
//                     correctly (our header over the file's own bytes), a
//                     canonical transcoded body for the rest, then OpenMesh's
//                     read and its count checks. The only place that knows
//                     OpenMesh's fragilities;
//   ply_tidy.cpp      the PointSet contract: finite positions, unit normals,
//                     positive radii.
// Before them, ply_header.cpp and ply_rows.cpp (ply_format.hpp) validate
// every byte; nothing here is sized from a header count they did not check.
#pragma once

#include <cstddef>
#include <glm/ext/vector_double3.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "attribute_column.hpp"
#include "ply_format.hpp"
#include "ply_openmesh.hpp"
#include "treecut/ply.hpp"
#include "treecut/point_set.hpp"

namespace treecut::ply_load {

using ply::Element;
using ply::Format;
using ply::Header;
using ply::Property;
using ply::Row;
using ply::Type;

// Vertex properties by meaning; -1 when absent. Normals and colours count only
// when all three components are present as scalars.
struct VertexRoles {
  int x = -1, y = -1, z = -1;
  int nx = -1, ny = -1, nz = -1;
  int red = -1, green = -1, blue = -1;
  int radius = -1;
  /// Every other scalar property (not alpha): kept as PointSet::attributes,
  /// at most kMaxAttributes.
  std::vector<int> attributes;

  [[nodiscard]] bool normals() const { return nx >= 0; }
  [[nodiscard]] bool colors() const { return red >= 0; }
};

class Warnings {
 public:
  Warnings(const std::string& name, const WarningSink& sink) : name_(name), sink_(sink) {}
  void operator()(const std::string& message) const {
    if (sink_) sink_(name_ + ": " + message);
  }

 private:
  const std::string& name_;
  const WarningSink& sink_;
};

inline const Property& property(const Element& element, int index) {
  return element.properties[static_cast<std::size_t>(index)];
}

// The index list of a face or tristrips element, or -1.
inline int index_property(const Element& element) {
  int p = element.find("vertex_indices");
  return p >= 0 ? p : element.find("vertex_index");
}

inline std::string plural(std::size_t n, const std::string& word) {
  return std::to_string(n) + " " + word + (n == 1 ? "" : "s");
}

// Collects tristrips as triangles. A negative index restarts the strip; odd
// triangles are flipped to keep the winding; the degenerate triangles strips
// use as stitches are skipped.
struct StripSink {
  std::size_t vertices = 0;
  std::vector<glm::uvec3> triangles;
  std::size_t out_of_range = 0;
  std::vector<double> strip;

  void row(const Row& row, int indices) {
    const auto p = static_cast<std::size_t>(indices);
    strip.clear();
    for (std::size_t k = 0; k < row.size[p]; ++k) {
      const double v = row.values[row.first[p] + k];
      if (v < 0) {
        flush();
        strip.clear();
      } else {
        strip.push_back(v);
      }
    }
    flush();
  }

  void flush() {
    for (std::size_t k = 0; k + 2 < strip.size(); ++k) {
      double a = strip[k];
      double b = strip[k + 1];
      const double c = strip[k + 2];
      if (k % 2 == 1) std::swap(a, b);
      if (a == b || b == c || a == c) continue;
      const auto n = static_cast<double>(vertices);
      if (a >= n || b >= n || c >= n) {
        ++out_of_range;
        continue;
      }
      triangles.emplace_back(static_cast<unsigned>(a), static_cast<unsigned>(b),
                             static_cast<unsigned>(c));
    }
  }
};

// The elements load_ply uses, by index into Header::elements.
struct Elements {
  std::size_t vertex = 0;
  int face = -1;    ///< "face" with an index list, or -1
  int strips = -1;  ///< "tristrips" with an index list, or -1
  VertexRoles roles;
  std::vector<std::size_t> ignored;  ///< elements read past, in header order
  /// A face or tristrips element sits at or after a binary element that does
  /// not match its header: no faces are read, the points load as a cloud.
  bool faces_lost = false;
};

// An element after the vertex element that does not match its header.
struct BrokenElement {
  std::size_t index = 0;
  std::string problem;
};

// Everything the read needs: OpenMesh's input, the transcoded body it may
// point into, and what we read ourselves because OpenMesh does not.
struct Plan {
  ply::OpenMeshInput input;
  std::string vertex_bytes;  ///< transcoded vertex rows (unused when direct)
  std::string face_bytes;    ///< transcoded face rows (unused when direct)
  std::vector<float> radii;
  std::vector<glm::u8vec4> colors;     ///< colours OpenMesh does not read, or empty
  std::vector<glm::u16vec3> colors16;  ///< ushort colours as the file has them
  /// Positions of a type a float does not hold (double, 32-bit integers),
  /// as the file has them: they get an origin (position_frame.hpp).
  std::vector<glm::dvec3> doubles;
  std::vector<detail::AttributeColumn> attributes;  ///< VertexRoles::attributes, in order
  StripSink strips;
  std::vector<BrokenElement> broken;  ///< ascii elements whose rows do not match
  bool faces_lost = false;            ///< a face element is among them
  std::size_t trailing_lines = 0;     ///< ascii: non-blank lines after the last row
  /// Vertex rows whose position is finite in the file but past the float
  /// range (a double 1e300): they reach the PointSet as infinities, and the
  /// messages must not call them that.
  std::size_t finite_beyond_float = 0;
  /// The origin of double positions; chosen from them when not given (a
  /// streamed file's batches after the first take the first's).
  std::optional<glm::dvec3> origin;
};

// ---- ply_elements.cpp: what the file holds

// Elements from LOST_FROM on could not be located (a binary element that does
// not match its header); they are neither read nor listed as ignored.
Elements classify(const Header& header, const Warnings& warn, std::size_t lost_from);

// One warning for all ignored elements, naming the first few: a header may
// declare thousands. Elements that did not match their header have a warning
// of their own and are not listed again.
void warn_ignored(const Header& header, const Elements& elements,
                  const std::vector<BrokenElement>& broken, const Warnings& warn);

// What a later element that does not match its header costs, appended to its
// problem: the element (and, binary, every element after it, which can no
// longer be located) and, when it held faces, the faces.
std::string broken_consequence(const Header& header, std::size_t index, bool binary,
                               bool faces_lost);

// ---- ply_plan.cpp: the way to OpenMesh

// The value type of a PLY scalar type (PointAttribute::type).
ValueType value_type(Type type);

// Fills PLAN for OpenMesh: the file's own bytes under our header when
// OpenMesh's reader decodes the layout correctly, else a canonical body
// transcoded from the validated rows; either way with what we read ourselves
// (radius, non-uchar colours, tristrips).
void plan_openmesh_read(const Header& header, const ply::BinaryLayout& layout,
                        std::string_view file, const Elements& elements, Plan& plan);

// Runs OpenMesh, checks that it read exactly the rows it was given, and adds
// what we read ourselves.
PointSet read_plan(Plan& plan, const Warnings& warn, PlyLoadReport& report);

// ---- ply_tidy.cpp: the PointSet contract

// What tidy() dropped or cleared.
struct Tidied {
  std::size_t read = 0;                 // points it was given
  std::size_t nonfinite = 0, huge = 0;  // dropped: NaN or infinite, past 1e18
  std::size_t dropped_faces = 0;
  std::size_t undefined_normals = 0;     // set to zero
  std::size_t bad_radii = 0, radii = 0;  // of the kept points' radii (all cleared)
  Tidied& operator+=(const Tidied& o);
};

// Makes the PointSet contract hold: finite positions, unit (or zero)
// normals, radii all positive or none.
// FINITE_BEYOND_FLOAT: Plan::finite_beyond_float, named as too large, not
// as infinite. With BATCH (one batch of a streamed file, PlyReader) what is
// dropped or cleared is added there, not said, and a batch of no usable
// point is empty rather than an error: the reader says the file's totals.
void tidy(PointSet& points, const Warnings& warn, PlyLoadReport& report,
          std::size_t finite_beyond_float, Tidied* batch = nullptr);

// The warnings for what T counts, said as one read of the whole file says them.
void say(const Tidied& t, const Warnings& warn);

// The error for a file none of whose T.read points is usable.
std::string no_usable_points(const Tidied& t);

// ---- ply_load.cpp: the pipeline

// One batch of a streamed file (PlyReader): BYTES a PLY holding the batch's
// rows alone; ORIGIN as Plan::origin; what tidy() drops added to BATCH.
PointSet load_batch(std::string_view bytes, const std::string& name, PlyLoadReport& report,
                    const WarningSink& warn, const std::optional<glm::dvec3>& origin,
                    Tidied& batch);

}  // namespace treecut::ply_load
