// The per-point scalars of a LAS point record beyond position and RGB
// (ASPRS LAS 1.4 R15, tables 7-17 and the extra bytes record of section
// 2.5.13), each decoded the same way: a little-endian integer or float at a
// byte offset, optionally a bit field of it, times a scale plus an offset.
// las_read.cpp reads the records; this says what is in them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "attribute_column.hpp"
#include "treecut/las.hpp"

namespace treecut::detail {

class LasFields {
 public:
  /// The fields of INFO's point format and its extra bytes that fit in its
  /// records. What cannot be read (an extra-bytes field past the record, an
  /// undocumented or array type) is named in *not_kept.
  LasFields(const LasInfo& info, std::size_t points, std::vector<std::string>& not_kept);

  /// Decodes every field of the next COUNT records, of LENGTH bytes at
  /// RECORDS: field by field, so each loop has one type.
  void read(const unsigned char* records, std::size_t count, std::uint32_t length);

  /// The attributes whose values differ into OUT, in record order; returns
  /// "name value" of each constant one (keep_varying).
  std::vector<std::string> take(std::vector<PointAttribute>& out);

 private:
  enum class Raw : std::uint8_t { u8, i8, u16, i16, u32, i32, u64, i64, f32, f64 };
  struct Field {
    std::uint32_t at = 0;  // byte offset in the record
    Raw raw = Raw::u8;
    std::uint8_t shift = 0, bits = 0;  // a bit field of an integer (bits 0: all)
    double scale = 1.0, offset = 0.0;
    bool has_no_data = false;
    double no_data = 0.0;  // a raw value that means "none" (extra bytes)
    AttributeColumn column;
  };
  void add(std::string name, std::uint32_t at, Raw raw, std::uint8_t shift = 0,
           std::uint8_t bits = 0, double scale = 1.0);
  template <class T>
  static void decode_all(Field& f, const unsigned char* records, std::size_t count,
                         std::uint32_t length);

  std::size_t points_;
  std::vector<Field> fields_;
};

}  // namespace treecut::detail
