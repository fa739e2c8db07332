// Geographic input to a metric frame with PROJ (reproject.hpp).
#include "reproject.hpp"

#include <proj.h>
#include <proj_experimental.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "import/file_metadata.hpp"
#include "import/position_frame.hpp"
#include "treecut/error.hpp"

namespace treecut::detail {

namespace {

struct ContextDeleter {
  void operator()(PJ_CONTEXT* c) const { proj_context_destroy(c); }
};
struct PjDeleter {
  void operator()(PJ* p) const { proj_destroy(p); }
};
using Context = std::unique_ptr<PJ_CONTEXT, ContextDeleter>;
using Pj = std::unique_ptr<PJ, PjDeleter>;

// PROJ's last error in words, for a message.
std::string proj_error(PJ_CONTEXT* ctx) {
  const char* text = proj_context_errno_string(ctx, proj_context_errno(ctx));
  return text ? text : "PROJ cannot use it";
}

// The file's coordinate system as PROJ takes it: its WKT, else the GeoTIFF
// key's EPSG code; null when the file names none PROJ knows.
Pj source_crs(PJ_CONTEXT* ctx, const CrsRecords& r) {
  if (!r.wkt.empty()) return Pj(proj_create(ctx, r.wkt.c_str()));
  const std::string words = crs_text(r);  // "EPSG:4326 (geographic)"
  if (!words.starts_with("EPSG:")) return nullptr;
  return Pj(proj_create(ctx, words.substr(0, words.find(' ')).c_str()));
}

// The horizontal part of a compound system (its first component).
Pj horizontal(PJ_CONTEXT* ctx, Pj crs) {
  if (crs && proj_get_type(crs.get()) == PJ_TYPE_COMPOUND_CRS)
    return Pj(proj_crs_get_sub_crs(ctx, crs.get(), 0));
  return crs;
}

bool geographic(const PJ* crs) {
  const PJ_TYPE t = proj_get_type(crs);
  return t == PJ_TYPE_GEOGRAPHIC_2D_CRS || t == PJ_TYPE_GEOGRAPHIC_3D_CRS;
}

// "EPSG:32633" or the system's name.
std::string name_of(const PJ* crs) {
  const char* auth = proj_get_id_auth_name(crs, 0);
  const char* code = proj_get_id_code(crs, 0);
  if (auth && code) return std::string(auth) + ":" + code;
  const char* name = proj_get_name(crs);
  return name ? name : "an unnamed system";
}

// The UTM zone of (LON, LAT) on the datum of GEODETIC: EPSG's code where
// the datum is WGS 84, else a projected system made on the datum.
Pj utm_of(PJ_CONTEXT* ctx, const PJ* geodetic, double lon, double lat) {
  const int zone = std::clamp(static_cast<int>(std::floor((lon + 180.0) / 6.0)) + 1, 1, 60);
  const bool north = lat >= 0.0;
  if (name_of(geodetic) == "EPSG:4326" || name_of(geodetic) == "EPSG:4979") {
    const std::string code = "EPSG:" + std::to_string((north ? 32600 : 32700) + zone);
    return Pj(proj_create(ctx, code.c_str()));
  }
  const Pj conversion(proj_create_conversion_utm(ctx, zone, north ? 1 : 0));
  const Pj cs(proj_create_cartesian_2D_cs(ctx, PJ_CART2D_EASTING_NORTHING, "metre", 1.0));
  const std::string label = std::string(proj_get_name(geodetic) ? proj_get_name(geodetic) : "") +
                            " / UTM zone " + std::to_string(zone) + (north ? "N" : "S");
  return Pj(proj_create_projected_crs(ctx, label.c_str(), geodetic, conversion.get(), cs.get()));
}

}  // namespace

std::string reproject(PointSet& points, const std::string& target, const std::string& name) {
  const CrsRecords& records = points.frame.crs_records;
  const bool named = !records.empty();
  if (target.empty() && !crs_is_geographic(records)) return {};
  if (!named) {
    throw InputError(name + ": --crs " + target +
                     ": the file names no coordinate system to reproject from");
  }
  const Context ctx(proj_context_create());
  proj_log_level(ctx.get(), PJ_LOG_NONE);
  proj_context_set_enable_network(ctx.get(), 0);
  const Pj source = horizontal(ctx.get(), source_crs(ctx.get(), records));
  if (!source) {
    if (target.empty()) return {};  // a system PROJ does not know: drawn as it is
    throw InputError(name + ": its coordinate system (" + points.frame.crs +
                     ") is not one PROJ can reproject from: " + proj_error(ctx.get()));
  }
  // The points in the file's coordinates, in double.
  const std::size_t n = points.size();
  std::vector<glm::dvec3> xyz(n);
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (std::size_t i = 0; i < n; ++i) {
    xyz[i] = points.exact_positions.empty() ? points.frame.origin + glm::dvec3(points.positions[i])
                                            : points.exact_positions[i];
    lo = glm::min(lo, xyz[i]), hi = glm::max(hi, xyz[i]);
  }
  Pj destination;
  if (target.empty()) {
    // Longitude and latitude of the centre pick the zone (x is longitude:
    // LAS and GIS order, as PROJ's visualization order takes it).
    const Pj geodetic(proj_crs_get_geodetic_crs(ctx.get(), source.get()));
    destination = utm_of(ctx.get(), geodetic.get(), 0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y));
  } else {
    destination = horizontal(ctx.get(), Pj(proj_create(ctx.get(), target.c_str())));
    if (!destination) throw InputError("--crs '" + target + "': " + proj_error(ctx.get()));
  }
  const Pj raw(
      proj_create_crs_to_crs_from_pj(ctx.get(), source.get(), destination.get(), nullptr, nullptr));
  const Pj transform(raw ? proj_normalize_for_visualization(ctx.get(), raw.get()) : nullptr);
  if (!transform) {
    throw InputError(name + ": no transformation from " + name_of(source.get()) + " to " +
                     name_of(destination.get()) + ": " + proj_error(ctx.get()));
  }
  // x and y in place, z (ellipsoidal or orthometric height, metres) kept.
  if (n > 0) {
    proj_trans_generic(transform.get(), PJ_FWD, &xyz[0].x, sizeof(glm::dvec3), n, &xyz[0].y,
                       sizeof(glm::dvec3), n, nullptr, 0, 0, nullptr, 0, 0);
  }
  for (const glm::dvec3& p : xyz) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
      throw InputError(name + ": " + name_of(source.get()) + " to " + name_of(destination.get()) +
                       " gives no coordinates for some points (" +
                       "they lie outside what that system covers)");
    }
  }
  // Positions, origin and exact positions anew; the grid was the file's.
  points.exact_positions.clear();
  points.frame.resolution = points.frame.grid_offset = glm::dvec3(0.0);
  (void)place_points(std::move(xyz), points);
  const PJ_TYPE type = proj_get_type(destination.get());
  const char* kind = type == PJ_TYPE_PROJECTED_CRS   ? " (projected)"
                     : geographic(destination.get()) ? " (geographic)"
                                                     : "";
  const std::string words = name_of(destination.get()) + kind + ", from " +
                            (points.frame.crs.empty() ? name_of(source.get()) : points.frame.crs);
  const char* wkt = proj_as_wkt(ctx.get(), destination.get(), PJ_WKT1_GDAL, nullptr);
  points.frame.crs_records = CrsRecords{wkt ? wkt : "", {}, {}, {}};
  points.frame.crs = words;
  return words;
}

}  // namespace treecut::detail
