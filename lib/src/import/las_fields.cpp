// The per-point scalars of LAS point records (las_fields.hpp).
#include "las_fields.hpp"

#include <cstring>
#include <limits>
#include <type_traits>

#include "little_endian.hpp"

namespace treecut::detail {

namespace {

// Bytes of a point record of each format without the extra bytes (tables 7-17).
constexpr std::uint32_t kBaseLength[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
constexpr std::uint32_t kRawSize[10] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};

}  // namespace

void LasFields::add(std::string name, std::uint32_t at, Raw raw, std::uint8_t shift,
                    std::uint8_t bits, double scale) {
  Field f{at, raw, shift, bits, scale, 0.0, false, 0.0, AttributeColumn(std::move(name), points_)};
  fields_.push_back(std::move(f));
}

LasFields::LasFields(const LasInfo& info, std::size_t points, std::vector<std::string>& not_kept)
    : points_(points) {
  const int format = info.point_format;
  add("intensity", 12, Raw::u16);
  if (format <= 5) {
    // Legacy records: returns in one byte, flags above a 5-bit class.
    add("return_number", 14, Raw::u8, 0, 3);
    add("number_of_returns", 14, Raw::u8, 3, 3);
    add("scan_direction", 14, Raw::u8, 6, 1);
    add("edge_of_flight_line", 14, Raw::u8, 7, 1);
    add("classification", 15, Raw::u8, 0, 5);
    add("classification_flags", 15, Raw::u8, 5, 3);
    add("scan_angle", 16, Raw::i8);  // whole degrees
    add("user_data", 17, Raw::u8);
    add("point_source_id", 18, Raw::u16);
    if (format == 1 || format >= 3) add("gps_time", 20, Raw::f64);
  } else {
    add("return_number", 14, Raw::u8, 0, 4);
    add("number_of_returns", 14, Raw::u8, 4, 4);
    add("classification_flags", 15, Raw::u8, 0, 4);
    add("scanner_channel", 15, Raw::u8, 4, 2);
    add("scan_direction", 15, Raw::u8, 6, 1);
    add("edge_of_flight_line", 15, Raw::u8, 7, 1);
    add("classification", 16, Raw::u8);
    add("user_data", 17, Raw::u8);
    add("scan_angle", 18, Raw::i16, 0, 0, 0.006);  // steps of 0.006 degrees
    add("point_source_id", 20, Raw::u16);
    add("gps_time", 22, Raw::f64);
    if (format == 8 || format == 10) add("nir", 36, Raw::u16);
  }

  std::uint32_t at = kBaseLength[format];
  for (const LasExtraBytes& e : info.extra_bytes) {
    const std::string name = e.name.empty() ? "extra_" + std::to_string(at) : e.name;
    // Types 11-30 (arrays, deprecated in 1.4) are 2 or 3 of types 1-10.
    const int t = e.data_type;
    const std::uint32_t size = t == 0    ? e.options
                               : t <= 10 ? kRawSize[t - 1]
                               : t <= 30 ? kRawSize[(t - 1) % 10] * ((t - 1) / 10 + 1)
                                         : 0;
    if (size == 0 || at + size > info.record_length) {
      // Nothing after an unreadable field can be located either.
      not_kept.push_back(name + (size == 0 ? " (unknown type " + std::to_string(t) + ")"
                                           : " (past the record's end)"));
      break;
    }
    if (t == 0 || t > 10) {
      not_kept.push_back(name + (t == 0 ? " (undocumented bytes)" : " (an array)"));
    } else if (fields_.size() < kMaxAttributes) {
      add(name, at, static_cast<Raw>(t - 1));
      Field& f = fields_.back();
      if (e.options & 8) f.scale = e.scale;
      if (e.options & 16) f.offset = e.offset;
      f.has_no_data = (e.options & 1) != 0;
      f.no_data = e.no_data;
    } else {
      not_kept.push_back(name + " (more than " + std::to_string(kMaxAttributes) + " attributes)");
    }
    at += size;
  }
}

// One field of every record: the raw value (a bit field of it), times the
// scale plus the offset, or no value where it equals the no-data value.
template <class T>
void LasFields::decode_all(Field& f, const unsigned char* records, std::size_t count,
                           std::uint32_t length) {
  const unsigned char* p = records + f.at;
  const unsigned mask = f.bits == 0 ? ~0u : (1u << f.bits) - 1u;
  for (std::size_t i = 0; i < count; ++i, p += length) {
    double raw;
    if constexpr (std::is_same_v<T, std::uint8_t>) {
      raw = double((unsigned{*p} >> f.shift) & mask);
    } else {
      raw = static_cast<double>(get_le<T>(p));
    }
    f.column.push_back(f.has_no_data && raw == f.no_data ? std::numeric_limits<double>::quiet_NaN()
                                                         : raw * f.scale + f.offset);
  }
}

void LasFields::read(const unsigned char* records, std::size_t count, std::uint32_t length) {
  for (Field& f : fields_) {
    switch (f.raw) {
      case Raw::u8:
        decode_all<std::uint8_t>(f, records, count, length);
        break;
      case Raw::i8:
        decode_all<std::int8_t>(f, records, count, length);
        break;
      case Raw::u16:
        decode_all<std::uint16_t>(f, records, count, length);
        break;
      case Raw::i16:
        decode_all<std::int16_t>(f, records, count, length);
        break;
      case Raw::u32:
        decode_all<std::uint32_t>(f, records, count, length);
        break;
      case Raw::i32:
        decode_all<std::int32_t>(f, records, count, length);
        break;
      case Raw::u64:
        decode_all<std::uint64_t>(f, records, count, length);
        break;
      case Raw::i64:
        decode_all<std::int64_t>(f, records, count, length);
        break;
      case Raw::f32:
        decode_all<float>(f, records, count, length);
        break;
      case Raw::f64:
        decode_all<double>(f, records, count, length);
        break;
    }
  }
}

std::vector<std::string> LasFields::take(std::vector<PointAttribute>& out) {
  std::vector<AttributeColumn> columns;
  for (Field& f : fields_) columns.push_back(std::move(f.column));
  fields_.clear();
  return keep_varying(columns, out);
}

}  // namespace treecut::detail
