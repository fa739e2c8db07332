// Geographic coordinates to a metric frame (issue 43, item 10), with PROJ
// (libproj-dev, Debian 12's PROJ 9.1). A LAS in EPSG:4326 holds longitude
// and latitude in degrees and heights in metres: drawn as they are, a
// survey is a needle five pixels wide. Such input goes to the UTM zone of
// its centre on its own datum (EPSG:326zz/327zz for WGS 84), or to the
// system `--crs` names; projected input stays in its system unless `--crs`
// names another. Private to the library (model_io.cpp calls it between the
// read and the build).
#pragma once

#include <string>

#include "treecut/point_set.hpp"

namespace treecut::detail {

/// Reprojects POINTS (their file coordinates, frame and exact positions)
/// to TARGET (an authority code such as "EPSG:32633", a WKT or a PROJ
/// string; empty: the UTM zone of the centre where the points are
/// geographic, else nothing). Returns what was done in words ("EPSG:32633
/// (projected), from EPSG:4326 (geographic)"), which becomes frame.crs;
/// empty when nothing was. Throws InputError "NAME: ..." when TARGET or the
/// file's system cannot be used (NAME: the model as messages show it).
std::string reproject(PointSet& points, const std::string& target, const std::string& name);

}  // namespace treecut::detail
