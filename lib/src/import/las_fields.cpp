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

void LasFields::add(std::string name, std::uint32_t at, ValueType raw, std::uint8_t shift,
                    std::uint8_t bits, double scale, double offset, std::optional<double> no_data) {
  Field f{at,
          raw,
          shift,
          bits,
          scale,
          offset,
          no_data.has_value(),
          no_data.value_or(0.0),
          AttributeColumn(std::move(name), points_, raw, scale, offset, no_data)};
  fields_.push_back(std::move(f));
}

LasFields::LasFields(const LasInfo& info, std::size_t points, std::vector<std::string>& not_kept)
    : points_(points) {
  const int format = info.point_format;
  add("intensity", 12, ValueType::u16);
  if (format <= 5) {
    // Legacy records: returns in one byte, flags above a 5-bit class.
    add("return_number", 14, ValueType::u8, 0, 3);
    add("number_of_returns", 14, ValueType::u8, 3, 3);
    add("scan_direction", 14, ValueType::u8, 6, 1);
    add("edge_of_flight_line", 14, ValueType::u8, 7, 1);
    add("classification", 15, ValueType::u8, 0, 5);
    add("classification_flags", 15, ValueType::u8, 5, 3);
    add("scan_angle", 16, ValueType::i8);  // whole degrees
    add("user_data", 17, ValueType::u8);
    add("point_source_id", 18, ValueType::u16);
    if (format == 1 || format >= 3) add("gps_time", 20, ValueType::f64);
  } else {
    add("return_number", 14, ValueType::u8, 0, 4);
    add("number_of_returns", 14, ValueType::u8, 4, 4);
    add("classification_flags", 15, ValueType::u8, 0, 4);
    add("scanner_channel", 15, ValueType::u8, 4, 2);
    add("scan_direction", 15, ValueType::u8, 6, 1);
    add("edge_of_flight_line", 15, ValueType::u8, 7, 1);
    add("classification", 16, ValueType::u8);
    add("user_data", 17, ValueType::u8);
    add("scan_angle", 18, ValueType::i16, 0, 0, 0.006);  // steps of 0.006 degrees
    add("point_source_id", 20, ValueType::u16);
    add("gps_time", 22, ValueType::f64);
    if (format == 8 || format == 10) add("nir", 36, ValueType::u16);
  }

  // The extra bytes, every one kept (issue 43): a field by its
  // descriptor, an array's elements and undocumented bytes as fields of
  // their own ("name[k]"; written back as plain extra-bytes fields), and
  // bytes no descriptor covers as bytes ("extra_N").
  std::uint32_t at = kBaseLength[format];
  auto keep = [&](std::string name, std::uint32_t where, ValueType type, double scale,
                  double offset, std::optional<double> no_data) {
    if (fields_.size() < kMaxAttributes) {
      add(std::move(name), where, type, 0, 0, scale, offset, no_data);
    } else {
      not_kept.push_back(name + " (more than " + std::to_string(kMaxAttributes) + " attributes)");
    }
  };
  for (const LasExtraBytes& e : info.extra_bytes) {
    const std::string name = e.name.empty() ? "extra_" + std::to_string(at) : e.name;
    // Types 11-30 (arrays, deprecated in 1.4) are 2 or 3 of types 1-10.
    const int t = e.data_type;
    const std::uint32_t elements = t == 0 ? e.options : t <= 10 ? 1 : ((t - 1) / 10 + 1);
    const std::uint32_t element = t == 0 ? 1 : t <= 30 ? kRawSize[(t - 1) % 10] : 0;
    const std::uint32_t size = elements * element;
    if (size == 0 || at + size > info.record_length) {
      // Nothing after an unreadable field can be located either.
      not_kept.push_back(name + (size == 0 ? " (unknown type " + std::to_string(t) + ")"
                                           : " (past the record's end)"));
      return;
    }
    const ValueType type = t == 0 ? ValueType::u8 : static_cast<ValueType>((t - 1) % 10);
    for (std::uint32_t k = 0; k < elements; ++k) {
      const bool array = t == 0 ? elements > 1 : t > 10;
      const std::uint32_t slot = t == 0 ? 0 : k;
      keep(array ? name + "[" + std::to_string(k) + "]" : name, at + k * element, type,
           t != 0 && (e.options & 8) ? e.scale[slot] : 1.0,
           t != 0 && (e.options & 16) ? e.offset[slot] : 0.0,
           t != 0 && (e.options & 1) ? std::optional<double>(e.no_data[slot]) : std::nullopt);
    }
    at += size;
  }
  for (; at < info.record_length; ++at)
    keep("extra_" + std::to_string(at), at, ValueType::u8, 1.0, 0.0, {});
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
    } else if constexpr (sizeof(T) == 8 && std::is_integral_v<T>) {
      const T v = get_le<T>(p);
      if (!f.has_no_data) {
        // Exactly, past 2^53 too (AttributeColumn::push_back_raw64).
        f.column.push_back_raw64(static_cast<std::uint64_t>(v));
        continue;
      }
      raw = static_cast<double>(v);
      constexpr T kExact = T{1} << 53;  // a double's integers
      f.column.rounded += v > kExact || (std::is_signed_v<T> && v < -kExact);
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
      case ValueType::u8:
        decode_all<std::uint8_t>(f, records, count, length);
        break;
      case ValueType::i8:
        decode_all<std::int8_t>(f, records, count, length);
        break;
      case ValueType::u16:
        decode_all<std::uint16_t>(f, records, count, length);
        break;
      case ValueType::i16:
        decode_all<std::int16_t>(f, records, count, length);
        break;
      case ValueType::u32:
        decode_all<std::uint32_t>(f, records, count, length);
        break;
      case ValueType::i32:
        decode_all<std::int32_t>(f, records, count, length);
        break;
      case ValueType::u64:
        decode_all<std::uint64_t>(f, records, count, length);
        break;
      case ValueType::i64:
        decode_all<std::int64_t>(f, records, count, length);
        break;
      case ValueType::f32:
        decode_all<float>(f, records, count, length);
        break;
      case ValueType::f64:
        decode_all<double>(f, records, count, length);
        break;
    }
  }
}

std::vector<std::string> LasFields::take(std::vector<PointAttribute>& out) {
  std::vector<std::string> rounded;
  for (Field& f : fields_) {
    const std::size_t r = f.column.rounded;
    out.push_back(f.column.take());
    if (r > 0) rounded.push_back(out.back().name + " (" + std::to_string(r) + " values)");
  }
  fields_.clear();
  return rounded;
}

}  // namespace treecut::detail
