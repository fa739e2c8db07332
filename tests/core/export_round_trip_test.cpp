// Issue 43's acceptance: an export round trip LAS -> LAS, LAS -> PLY -> LAS
// and LAS -> PCD -> LAS keeps every field of every point to its file type's
// precision (integers, classification flags, GPS time, extra bytes, RGB bit
// depth) and the coordinate system. Compared field by field by a LAS decoder
// of this test's own, written from the ASPRS LAS 1.4 R15 tables, not the
// library's: on two files made here with every field varied (LAS 1.4 point
// format 7 and LAS 1.2 format 3) and on every LAS of ../shared/laz-pairs
// (files of laspy, laz-perf, laz-rs and LASzip).
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"

namespace {

namespace fs = std::filesystem;
using treecut::PointSet;
using namespace std::string_literals;

template <class T>
T get(const std::string& b, std::size_t at) {
  static_assert(std::endian::native == std::endian::little);
  T v;
  std::memcpy(&v, b.data() + at, sizeof v);
  return v;
}
template <class T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

// ---- The test's own decoder ------------------------------------------------

// A point: every field by name, the file's values (coordinates scaled and
// offset, extra bytes scaled and offset, no value as NaN).
using Fields = std::map<std::string, double>;

struct Decoded {
  int format = 0;
  bool adjusted_time = false;
  std::vector<Fields> points;
  std::map<std::string, std::string> records;  // "user/id" -> payload, but the extra bytes'
};

std::string text(const std::string& b, std::size_t at, std::size_t n) {
  std::string s = b.substr(at, n);
  s.resize(std::strlen(s.c_str()));
  return s;
}

double raw_value(const std::string& b, std::size_t at, int type) {
  switch (type) {
    case 1:
      return get<std::uint8_t>(b, at);
    case 2:
      return get<std::int8_t>(b, at);
    case 3:
      return get<std::uint16_t>(b, at);
    case 4:
      return get<std::int16_t>(b, at);
    case 5:
      return get<std::uint32_t>(b, at);
    case 6:
      return get<std::int32_t>(b, at);
    case 7:
      return static_cast<double>(get<std::uint64_t>(b, at));
    case 8:
      return static_cast<double>(get<std::int64_t>(b, at));
    case 9:
      return get<float>(b, at);
    default:
      return get<double>(b, at);
  }
}

struct Extra {
  std::string name;
  std::size_t at = 0;
  int type = 1;  // 1-10
  double scale = 1, offset = 0;
  bool has_no_data = false;
  double no_data = 0;
};

// The extra-bytes fields of a descriptor record: arrays and undocumented
// bytes element by element as "name[k]", bytes no descriptor covers as
// "extra_N" (the names treecut gives them, so results compare by name).
std::vector<Extra> extras(const std::string& payload, std::size_t base, std::size_t length) {
  std::vector<Extra> out;
  std::size_t at = base;
  for (std::size_t d = 0; d + 192 <= payload.size(); d += 192) {
    const int t = static_cast<unsigned char>(payload[d + 2]);
    const int options = static_cast<unsigned char>(payload[d + 3]);
    std::string name = text(payload, d + 4, 32);
    if (name.empty()) name = "extra_" + std::to_string(at);
    const int elements = t == 0 ? options : t <= 10 ? 1 : (t - 1) / 10 + 1;
    const int base_type = t == 0 ? 1 : (t - 1) % 10 + 1;
    static constexpr std::size_t kSize[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
    for (int k = 0; k < elements; ++k) {
      Extra e;
      e.name = (t == 0 ? elements > 1 : t > 10) ? name + "[" + std::to_string(k) + "]" : name;
      e.at = at + static_cast<std::size_t>(k) * kSize[base_type];
      e.type = base_type;
      if (t != 0 && (options & 8)) e.scale = get<double>(payload, d + 112 + 8 * k);
      if (t != 0 && (options & 16)) e.offset = get<double>(payload, d + 136 + 8 * k);
      if (t != 0 && (options & 1)) {
        e.has_no_data = true;
        e.no_data = base_type >= 9 ? get<double>(payload, d + 40 + 8 * k)
                    : base_type % 2 == 0
                        ? static_cast<double>(get<std::int64_t>(payload, d + 40 + 8 * k))
                        : static_cast<double>(get<std::uint64_t>(payload, d + 40 + 8 * k));
      }
      out.push_back(e);
    }
    at += static_cast<std::size_t>(elements) * kSize[base_type];
  }
  for (; at < length; ++at) out.push_back({"extra_" + std::to_string(at), at, 1});
  return out;
}

Decoded decode(const std::string& b) {
  Decoded d;
  const int minor = b[25];
  const std::size_t header = get<std::uint16_t>(b, 94);
  const std::size_t offset = get<std::uint32_t>(b, 96);
  const std::uint32_t vlr_count = get<std::uint32_t>(b, 100);
  d.format = b[104];
  const std::size_t length = get<std::uint16_t>(b, 105);
  std::uint64_t n = get<std::uint32_t>(b, 107);
  if (minor >= 4 && get<std::uint64_t>(b, 247) != 0) n = get<std::uint64_t>(b, 247);
  d.adjusted_time = (get<std::uint16_t>(b, 6) & 1) != 0;
  double scale[3], off[3];
  for (int a = 0; a < 3; ++a) {
    scale[a] = get<double>(b, 131 + 8 * a);
    off[a] = get<double>(b, 155 + 8 * a);
  }
  std::string descriptors;
  auto record = [&](const std::string& user, std::uint16_t id, const std::string& payload) {
    if (user == "LASF_Spec" && id == 4) {
      descriptors = payload;
    } else {
      d.records[user + "/" + std::to_string(id)] = payload;  // empty ones too
    }
  };
  std::size_t at = header;
  for (std::uint32_t i = 0; i < vlr_count; ++i) {
    const std::size_t size = get<std::uint16_t>(b, at + 20);
    record(text(b, at + 2, 16), get<std::uint16_t>(b, at + 18), b.substr(at + 54, size));
    at += 54 + size;
  }
  if (minor >= 4 && get<std::uint32_t>(b, 243) > 0) {
    at = get<std::uint64_t>(b, 235);
    for (std::uint32_t i = 0; i < get<std::uint32_t>(b, 243); ++i) {
      const std::size_t size = get<std::uint64_t>(b, at + 20);
      record(text(b, at + 2, 16), get<std::uint16_t>(b, at + 18), b.substr(at + 60, size));
      at += 60 + size;
    }
  }
  static constexpr std::size_t kBase[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  const std::vector<Extra> extra = extras(descriptors, kBase[d.format], length);
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::string r = b.substr(offset + i * length, length);
    Fields f;
    for (int a = 0; a < 3; ++a)
      f["xyz"[a] + std::string()] = get<std::int32_t>(r, 4 * a) * scale[a] + off[a];
    f["intensity"] = get<std::uint16_t>(r, 12);
    const unsigned b14 = static_cast<unsigned char>(r[14]), b15 = static_cast<unsigned char>(r[15]);
    if (d.format <= 5) {
      f["return_number"] = b14 & 7, f["number_of_returns"] = (b14 >> 3) & 7;
      f["scan_direction"] = (b14 >> 6) & 1, f["edge_of_flight_line"] = b14 >> 7;
      f["classification"] = b15 & 31, f["classification_flags"] = b15 >> 5;
      f["scan_angle"] = get<std::int8_t>(r, 16), f["user_data"] = get<std::uint8_t>(r, 17);
      f["point_source_id"] = get<std::uint16_t>(r, 18);
      if (d.format == 1 || d.format >= 3) f["gps_time"] = get<double>(r, 20);
    } else {
      f["return_number"] = b14 & 15, f["number_of_returns"] = b14 >> 4;
      f["classification_flags"] = b15 & 15, f["scanner_channel"] = (b15 >> 4) & 3;
      f["scan_direction"] = (b15 >> 6) & 1, f["edge_of_flight_line"] = b15 >> 7;
      f["classification"] = get<std::uint8_t>(r, 16), f["user_data"] = get<std::uint8_t>(r, 17);
      f["scan_angle"] = get<std::int16_t>(r, 18) * 0.006;
      f["point_source_id"] = get<std::uint16_t>(r, 20), f["gps_time"] = get<double>(r, 22);
    }
    static constexpr std::size_t kRgb[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};
    if (kRgb[d.format] != 0) {
      f["red"] = get<std::uint16_t>(r, kRgb[d.format]);
      f["green"] = get<std::uint16_t>(r, kRgb[d.format] + 2);
      f["blue"] = get<std::uint16_t>(r, kRgb[d.format] + 4);
    }
    if (d.format == 8 || d.format == 10) f["nir"] = get<std::uint16_t>(r, 36);
    for (const Extra& e : extra) {
      const double raw = raw_value(r, e.at, e.type);
      f[e.name] = e.has_no_data && raw == e.no_data ? NAN : raw * e.scale + e.offset;
    }
    d.points.push_back(std::move(f));
  }
  return d;
}

// Every field of every point of A is in B with the same value (NaN: both
// none), and so are the coordinate system's and the other records and the
// GPS time type. Returns the first difference, or "".
std::string compare(const Decoded& a, const Decoded& b) {
  if (a.points.size() != b.points.size()) return "point counts differ";
  if (a.adjusted_time != b.adjusted_time) return "the GPS time type differs";
  for (const auto& [key, payload] : a.records) {
    const auto it = b.records.find(key);
    if (it == b.records.end()) return "record " + key + " is lost";
    if (it->second != payload) return "record " + key + " differs";
  }
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    for (const auto& [name, value] : a.points[i]) {
      const auto it = b.points[i].find(name);
      // A channel of 0 in a legacy format's place is the legacy format's.
      if (it == b.points[i].end()) return "point " + std::to_string(i) + ": " + name + " is lost";
      const double v = it->second;
      const bool same = value == v || (std::isnan(value) && std::isnan(v));
      if (!same) {
        char line[160];
        std::snprintf(line, sizeof line, "point %zu: %s is %.17g, was %.17g", i, name.c_str(), v,
                      value);
        return line;
      }
    }
  }
  return "";
}

// ---- Files made here --------------------------------------------------------

struct Descriptor {
  std::string name;
  int type;  // 1-30; 0 undocumented (options bytes)
  int options = 0;
  double scale = 1, offset = 0;
  std::int64_t no_data = 0;
};

std::string descriptor_payload(const std::vector<Descriptor>& ds) {
  std::string v;
  for (const Descriptor& d : ds) {
    std::string r(192, '\0');
    r[2] = static_cast<char>(d.type);
    r[3] = static_cast<char>(d.options);
    std::memcpy(r.data() + 4, d.name.data(), d.name.size());
    std::memcpy(r.data() + 40, &d.no_data, 8);
    for (int k = 0; k < 3; ++k) {
      std::memcpy(r.data() + 112 + 8 * k, &d.scale, 8);
      std::memcpy(r.data() + 136 + 8 * k, &d.offset, 8);
    }
    v += r;
  }
  return v;
}

std::string vlr(const std::string& user, std::uint16_t id, const std::string& payload) {
  std::string v;
  put<std::uint16_t>(v, 0);
  std::string u = user;
  u.resize(16, '\0');
  v += u;
  put<std::uint16_t>(v, id);
  put<std::uint16_t>(v, static_cast<std::uint16_t>(payload.size()));
  v.append(32, '\0');
  return v + payload;
}

// A LAS file: version 1.MINOR, FORMAT, RECORDS (each of LENGTH bytes),
// VLRS, one EVLR (1.4), global encoding bits.
std::string las(int minor, int format, std::size_t length, const std::vector<std::string>& records,
                const std::string& vlrs, std::uint32_t vlr_count, std::uint16_t encoding,
                const std::string& evlr = "") {
  const std::size_t header = minor >= 4 ? 375 : 227;
  std::string h(header, '\0');
  std::memcpy(h.data(), "LASF", 4);
  std::memcpy(h.data() + 6, &encoding, 2);
  h[24] = 1, h[25] = static_cast<char>(minor);
  std::memcpy(h.data() + 58, "round trip test", 15);
  const std::uint16_t hs = static_cast<std::uint16_t>(header);
  std::memcpy(h.data() + 94, &hs, 2);
  const std::uint32_t offset = static_cast<std::uint32_t>(header + vlrs.size());
  std::memcpy(h.data() + 96, &offset, 4);
  std::memcpy(h.data() + 100, &vlr_count, 4);
  h[104] = static_cast<char>(format);
  const std::uint16_t len = static_cast<std::uint16_t>(length);
  std::memcpy(h.data() + 105, &len, 2);
  const std::uint32_t legacy = format <= 5 ? static_cast<std::uint32_t>(records.size()) : 0;
  std::memcpy(h.data() + 107, &legacy, 4);
  const double scale[3] = {0.001, 0.001, 0.0001}, off[3] = {500000.0, 5000000.0, 0.0};
  std::memcpy(h.data() + 131, scale, 24);
  std::memcpy(h.data() + 155, off, 24);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const std::string& r : records) {
    for (int a = 0; a < 3; ++a) {
      const double v = get<std::int32_t>(r, 4 * a) * scale[a] + off[a];
      lo[a] = std::min(lo[a], v), hi[a] = std::max(hi[a], v);
    }
  }
  for (int a = 0; a < 3; ++a) {
    std::memcpy(h.data() + 179 + 16 * a, &hi[a], 8);
    std::memcpy(h.data() + 187 + 16 * a, &lo[a], 8);
  }
  if (minor >= 4) {
    const std::uint64_t count = records.size();
    std::memcpy(h.data() + 247, &count, 8);
    if (!evlr.empty()) {
      const std::uint64_t start = header + vlrs.size() + records.size() * length;
      const std::uint32_t one = 1;
      std::memcpy(h.data() + 235, &start, 8);
      std::memcpy(h.data() + 243, &one, 4);
    }
  }
  std::string out = h + vlrs;
  for (const std::string& r : records) out += r;
  if (!evlr.empty()) {
    std::string e;
    put<std::uint16_t>(e, 0);
    std::string u = "vendor";
    u.resize(16, '\0');
    e += u;
    put<std::uint16_t>(e, 77);
    put<std::uint64_t>(e, evlr.size());
    e.append(32, '\0');
    out += e + evlr;
  }
  return out;
}

// LAS 1.4 format 7: every field varied (classes past 31, 15 returns, the
// overlap flag, every channel, 0.006-degree scan angles, GPS week times to
// the microsecond, 16-bit RGB), extra bytes of eight types (a scaled short
// with a no-data value, a 64-bit integer past 2^32, a double of 1e300, a
// deprecated array), a WKT, a record of another program's and an EVLR.
std::string made_las14() {
  std::mt19937_64 rng(43);
  const std::vector<Descriptor> ds = {
      {"quality", 1},     {"height", 4, 1 | 8 | 16, 0.01, 100.0, -32768},
      {"count", 5},       {"id", 8},
      {"reflectance", 9}, {"big", 10},
      {"pair", 13},  // 2 x ushort (deprecated array)
  };
  const std::size_t length = 36 + 1 + 2 + 4 + 8 + 4 + 8 + 4;
  std::vector<std::string> records;
  for (int i = 0; i < 400; ++i) {
    std::string r;
    put<std::int32_t>(r, static_cast<std::int32_t>(rng() % 2000000) - 1000000);
    put<std::int32_t>(r, static_cast<std::int32_t>(rng() % 2000000) - 1000000);
    put<std::int32_t>(r, static_cast<std::int32_t>(rng() % 3000000));
    put<std::uint16_t>(r, static_cast<std::uint16_t>(rng()));
    const unsigned ret = 1 + rng() % 15;
    r.push_back(static_cast<char>(ret | ((ret + rng() % (16 - ret)) << 4)));
    r.push_back(static_cast<char>(rng()));  // flags, channel, direction, edge: all bits
    r.push_back(static_cast<char>(rng()));  // class 0-255
    r.push_back(static_cast<char>(rng()));  // user data
    put<std::int16_t>(r, static_cast<std::int16_t>(static_cast<int>(rng() % 60001) - 30000));
    put<std::uint16_t>(r, static_cast<std::uint16_t>(rng()));
    put<double>(r, 245379.398412 + 1e-6 * double(rng() % 10000000));
    for (int c = 0; c < 3; ++c) put<std::uint16_t>(r, static_cast<std::uint16_t>(rng()));
    r.push_back(static_cast<char>(rng()));
    put<std::int16_t>(r, i % 17 == 0
                             ? std::int16_t{-32768}
                             : static_cast<std::int16_t>(static_cast<int>(rng() % 60000) - 30000));
    put<std::uint32_t>(r, static_cast<std::uint32_t>(rng()));
    put<std::int64_t>(
        r, static_cast<std::int64_t>(rng() % (std::uint64_t{1} << 50)) * (i % 2 ? 1 : -1));
    put<float>(r, static_cast<float>(rng() % 100000) * 1.37e-3f);
    put<double>(r, i % 3 == 0 ? 1e300 : i % 3 == 1 ? -1e-300 : double(rng()) * 0.5);
    put<std::uint16_t>(r, static_cast<std::uint16_t>(rng()));
    put<std::uint16_t>(r, static_cast<std::uint16_t>(rng()));
    EXPECT_EQ(r.size(), length);
    records.push_back(r);
  }
  const std::string wkt =
      "PROJCS[\"WGS 84 / UTM zone 33N\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS "
      "84\",6378137,298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],"
      "PROJECTION[\"Transverse_Mercator\"],AUTHORITY[\"EPSG\",\"32633\"]]";
  const std::string vlrs = vlr("LASF_Projection", 2112, wkt + std::string(1, '\0')) +
                           vlr("LASF_Spec", 4, descriptor_payload(ds)) +
                           vlr("some vendor", 12345, "its own bytes \x01\x02");
  return las(4, 7, length, records, vlrs, 3, 16, "an extended record");
}

// LAS 1.2 format 3: 8-bit colours in the 16-bit fields, adjusted standard
// GPS time, GeoTIFF keys (projected 26915 over geographic 4269) with an
// ASCII parameter record, an unsigned short and two undocumented bytes.
std::string made_las12() {
  std::mt19937_64 rng(12);
  const std::vector<Descriptor> ds = {{"amplitude", 3}, {"vendor", 0, 2}};
  const std::size_t length = 34 + 2 + 2;
  std::vector<std::string> records;
  for (int i = 0; i < 300; ++i) {
    std::string r;
    for (int a = 0; a < 3; ++a) put<std::int32_t>(r, static_cast<std::int32_t>(rng() % 100000));
    put<std::uint16_t>(r, static_cast<std::uint16_t>(rng()));
    r.push_back(static_cast<char>(rng()));
    r.push_back(static_cast<char>(rng()));
    r.push_back(static_cast<char>(static_cast<int>(rng() % 181) - 90));
    r.push_back(static_cast<char>(rng()));
    put<std::uint16_t>(r, static_cast<std::uint16_t>(rng() % 3));
    put<double>(r, 1.2e8 + 1e-6 * double(rng() % 1000000000));
    for (int c = 0; c < 3; ++c) put<std::uint16_t>(r, static_cast<std::uint16_t>(rng() % 256));
    put<std::uint16_t>(r, static_cast<std::uint16_t>(rng()));
    r.push_back(static_cast<char>(rng()));
    r.push_back(static_cast<char>(rng()));
    records.push_back(r);
  }
  std::string keys;
  for (const std::uint16_t v :
       {1, 1, 0, 4, 1024, 0, 1, 1, 2048, 0, 1, 4269, 3072, 0, 1, 26915, 3073, 34737, 24, 0})
    put<std::uint16_t>(keys, v);
  const std::string vlrs = vlr("LASF_Projection", 34735, keys) +
                           vlr("LASF_Projection", 34737, "NAD83 / UTM zone 15N|\0"s) +
                           vlr("LASF_Spec", 4, descriptor_payload(ds));
  return las(2, 3, length, records, vlrs, 3, 1);
}

std::string read_file(const fs::path& p) {
  return treecut::test::read_all(p);
}

// The three round trips of SOURCE (a LAS file on disk), each compared with it.
void round_trips(const fs::path& source, const fs::path& dir) {
  const Decoded original = decode(read_file(source));
  const PointSet points = treecut::load_las(source);
  treecut::save_las(dir / "direct.las", points);
  EXPECT_EQ(compare(original, decode(read_file(dir / "direct.las"))), "") << "LAS -> LAS";

  treecut::save_ply(dir / "via.ply", points);
  treecut::save_las(dir / "via_ply.las", treecut::load_ply(dir / "via.ply"));
  EXPECT_EQ(compare(original, decode(read_file(dir / "via_ply.las"))), "") << "LAS -> PLY -> LAS";

  treecut::save_pcd(dir / "via.pcd", points);
  treecut::save_las(dir / "via_pcd.las", treecut::load_pcd(dir / "via.pcd"));
  EXPECT_EQ(compare(original, decode(read_file(dir / "via_pcd.las"))), "") << "LAS -> PCD -> LAS";
}

TEST(ExportRoundTrip, ALas14FileOfEveryFieldKeepsEveryOne) {
  const fs::path dir = treecut::test::scratch_dir("round_trip_14");
  treecut::test::write_text(dir / "source.las", made_las14());
  const Decoded d = decode(read_file(dir / "source.las"));
  ASSERT_EQ(d.points.size(), 400u);
  ASSERT_EQ(d.format, 7);
  round_trips(dir / "source.las", dir);
  // The written file is LAS 1.4 format 7 again: nothing fits a smaller one.
  EXPECT_EQ(decode(read_file(dir / "via_ply.las")).format, 7);
}

TEST(ExportRoundTrip, ALas12FileKeepsEightBitColoursKeysAndUndocumentedBytes) {
  const fs::path dir = treecut::test::scratch_dir("round_trip_12");
  treecut::test::write_text(dir / "source.las", made_las12());
  round_trips(dir / "source.las", dir);
  EXPECT_EQ(decode(read_file(dir / "via_pcd.las")).format, 3);
}

// Files other libraries wrote (../shared/laz-pairs: laspy, laz-perf, laz-rs,
// LASzip), every one with points.
TEST(ExportRoundTrip, EveryLasOfOtherLibrariesKeepsEveryField) {
  const auto shared = treecut::test::shared_dir();
  if (!shared || !fs::exists(*shared / "laz-pairs"))
    GTEST_SKIP() << "../shared/laz-pairs is absent";
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(*shared / "laz-pairs")) {
    if (e.path().extension() != ".las") continue;
    const Decoded d = decode(read_file(e.path()));
    if (d.points.empty()) continue;
    SCOPED_TRACE(e.path().filename().string());
    const fs::path dir = treecut::test::scratch_dir("round_trip_" + e.path().stem().string());
    round_trips(e.path(), dir);
    ++files;
  }
  EXPECT_GE(files, 15u);
}

// The decoder itself sees a difference: a flipped classification bit and a
// GPS time off by a microsecond are named, a lost record too.
TEST(ExportRoundTrip, TheComparisonNamesADifference) {
  const std::string bytes = made_las14();
  const Decoded a = decode(bytes);
  Decoded b = a;
  b.points[5]["classification"] += 1;
  EXPECT_NE(compare(a, b).find("point 5: classification"), std::string::npos);
  b = a;
  b.points[9]["gps_time"] += 1e-6;
  EXPECT_NE(compare(a, b).find("point 9: gps_time"), std::string::npos);
  b = a;
  b.records.erase("LASF_Projection/2112");
  EXPECT_NE(compare(a, b).find("record LASF_Projection/2112 is lost"), std::string::npos);
}

}  // namespace
