// Writing an attribute's values in a type that holds them (issue 43): the
// writers' shared rule (LAS extra bytes, PLY properties, PCD fields).
#pragma once

#include <cstddef>
#include <string>

#include "treecut/point_set.hpp"

namespace treecut::detail {

/// The type A is written in by a format without a scale and offset (PLY,
/// PCD): the file's own where it holds every value; a double for a scaled
/// value (a LAS scan angle, an extra-bytes field with a scale), for an
/// integer column with no value somewhere (NaN), and, where the format has
/// no 64-bit integers (NO_INT64), for those. N: the points.
ValueType output_type(const PointAttribute& a, std::size_t n, bool no_int64);

/// Whether some point of A (of N) has no value.
bool has_missing(const PointAttribute& a, std::size_t n);

/// Appends RAW in TYPE, little-endian: integers rounded and clamped to the
/// type's range, NaN as 0 (callers pick a type that holds what they write).
void put_value(std::string& out, ValueType type, double raw);

/// RAW as text for TYPE: integers in decimal, floats to their precision
/// (9 and 17 significant digits), NaN as "nan".
std::string value_text(ValueType type, double raw);

}  // namespace treecut::detail
