// The per-point scalars of a LAS point record beyond position and RGB
// (ASPRS LAS 1.4 R15, tables 7-17 and the extra bytes record of section
// 2.5.13), each decoded the same way: a little-endian integer or float at a
// byte offset, optionally a bit field of it, times a scale plus an offset.
// las_read.cpp reads the records; this says what is in them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
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

  /// Every attribute into OUT, in record order; returns the names of those
  /// with 64-bit integers beyond 2^53, which a double rounds.
  std::vector<std::string> take(std::vector<PointAttribute>& out);

 private:
  struct Field {
    std::uint32_t at = 0;  // byte offset in the record
    ValueType raw = ValueType::u8;
    std::uint8_t shift = 0, bits = 0;  // a bit field of an integer (bits 0: all)
    double scale = 1.0, offset = 0.0;
    bool has_no_data = false;
    double no_data = 0.0;  // a raw value that means "none" (extra bytes)
    AttributeColumn column;
  };
  void add(std::string name, std::uint32_t at, ValueType raw, std::uint8_t shift = 0,
           std::uint8_t bits = 0, double scale = 1.0, double offset = 0.0,
           std::optional<double> no_data = {});
  template <class T>
  static void decode_all(Field& f, const unsigned char* records, std::size_t count,
                         std::uint32_t length);

  std::size_t points_;
  std::vector<Field> fields_;
};

}  // namespace treecut::detail
