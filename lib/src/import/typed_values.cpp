// The writers' types (typed_values.hpp).
#include "typed_values.hpp"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "little_endian.hpp"

namespace treecut::detail {

bool has_missing(const PointAttribute& a, std::size_t n) {
  if (a.is_constant()) return n > 0 && std::isnan(a.constant);
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isnan(a.value(i))) return true;
  }
  return false;
}

ValueType output_type(const PointAttribute& a, std::size_t n, bool no_int64) {
  if (a.scale != 1.0 || a.base != 0.0) return ValueType::f64;
  if (!is_integer(a.type)) return a.type;
  const bool wide = a.type == ValueType::u64 || a.type == ValueType::i64;
  if ((no_int64 && wide) || has_missing(a, n)) return ValueType::f64;
  return a.type;
}

namespace {

template <class T>
T clamped(double v) {
  if (std::isnan(v)) return T{0};
  // The largest doubles below 2^63 and 2^64 (the bounds themselves overflow).
  const double lo = std::is_signed_v<T> ? (sizeof(T) == 8 ? -9223372036854775808.0
                                                          : double(std::numeric_limits<T>::min()))
                                        : 0.0;
  const double hi = sizeof(T) == 8
                        ? (std::is_signed_v<T> ? 9223372036854774784.0 : 18446744073709549568.0)
                        : double(std::numeric_limits<T>::max());
  return static_cast<T>(std::clamp(std::round(v), lo, hi));
}

}  // namespace

void put_value(std::string& out, ValueType type, double raw) {
  switch (type) {
    case ValueType::u8:
      return put_le(out, clamped<std::uint8_t>(raw));
    case ValueType::i8:
      return put_le(out, clamped<std::int8_t>(raw));
    case ValueType::u16:
      return put_le(out, clamped<std::uint16_t>(raw));
    case ValueType::i16:
      return put_le(out, clamped<std::int16_t>(raw));
    case ValueType::u32:
      return put_le(out, clamped<std::uint32_t>(raw));
    case ValueType::i32:
      return put_le(out, clamped<std::int32_t>(raw));
    case ValueType::u64:
      return put_le(out, clamped<std::uint64_t>(raw));
    case ValueType::i64:
      return put_le(out, clamped<std::int64_t>(raw));
    case ValueType::f32:
      return put_le(out, static_cast<float>(raw));
    case ValueType::f64:
      return put_le(out, raw);
  }
}

std::string value_text(ValueType type, double raw) {
  char text[40];
  if (std::isnan(raw)) return "nan";
  if (type == ValueType::f32) {
    std::snprintf(text, sizeof text, "%.9g", double(static_cast<float>(raw)));
  } else if (type == ValueType::f64) {
    std::snprintf(text, sizeof text, "%.17g", raw);
  } else if (is_signed(type)) {
    std::snprintf(text, sizeof text, "%" PRId64, clamped<std::int64_t>(raw));
  } else {
    std::snprintf(text, sizeof text, "%" PRIu64, clamped<std::uint64_t>(raw));
  }
  return text;
}

}  // namespace treecut::detail
