// Binary point files read in batches (PlyReader, PcdReader; issue 44 item
// 1): a file read a batch of rows at a time gives the points, the report
// and the warnings that one read gives, whatever the batch size, and a
// file the reader cannot cut is one batch of the whole read.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <type_traits>
#include <vector>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;

// Every point of a set, in map coordinates, with what it carries.
struct Points {
  std::vector<glm::dvec3> at;
  std::vector<glm::vec3> normals;
  std::vector<glm::u8vec4> colors;
  std::vector<float> radii;
  std::vector<double> values;
  void add(const PointSet& b) {
    for (std::size_t i = 0; i < b.size(); ++i) {
      at.push_back(b.frame.origin + glm::dvec3(b.positions[i]));
      if (b.has_normals()) normals.push_back(b.normals[i]);
      if (b.has_colors()) colors.push_back(b.colors[i]);
      if (b.has_radii()) radii.push_back(b.radii[i]);
      if (!b.attributes.empty()) values.push_back(b.attributes[0].value(i));
    }
  }
  bool operator==(const Points&) const = default;
};

// A scanner's cloud in map coordinates (doubles in the file), with
// normals, colours, radii and an intensity; points 5 and 6 have no
// position, point 9 no normal. Positions on a 1/256 grid within 100 m of
// (500000, 5000000, 300): floats give them back from any whole origin near.
PointSet scan(std::size_t n) {
  PointSet ps;
  ps.frame.origin = glm::dvec3(500000.0, 5000000.0, 300.0);
  PointAttribute intensity;
  intensity.name = "intensity";
  intensity.type = ValueType::u16;
  for (std::size_t i = 0; i < n; ++i) {
    const double u = double(i % 997) / 8.0, v = double(i / 997) / 4.0, w = double(i % 13) / 256.0;
    ps.positions.emplace_back(float(u - 60.0), float(v - 50.0), float(w));
    ps.normals.emplace_back(0.0f, 0.6f, 0.8f);
    ps.colors.emplace_back(i % 256, (i / 256) % 256, 7, 255);
    ps.radii.push_back(0.05f + float(i % 5) / 64.0f);
    intensity.values.push_back(float(i % 4000));
  }
  ps.attributes.push_back(std::move(intensity));
  return ps;
}

std::string ply_bytes(const PointSet& ps, const fs::path& dir) {
  save_ply(dir / "scan.ply", ps);
  return test::read_all(dir / "scan.ply");
}

// NaN in a file's doubles: positions 5 and 6 (x, y, z: 8 bytes each) and
// normal 9's x (a float after the three doubles).
void spoil(std::string& ply, std::size_t stride) {
  const std::size_t body = ply.find("end_header\n") + 11;
  const double nan = std::nan("");
  const float fnan = std::nanf("");
  std::memcpy(ply.data() + body + 5 * stride, &nan, 8);
  std::memcpy(ply.data() + body + 6 * stride + 16, &nan, 8);
  std::memcpy(ply.data() + body + 9 * stride + 24, &fnan, 4);
}

// The InputError message READ throws, or empty.
template <class Fn>
std::string error_of(Fn&& read) {
  try {
    (void)read();
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

struct Read {
  Points points;
  std::vector<std::string> warnings;
  std::size_t batches = 0;
  PlyLoadReport report;
};

template <class Reader>
Read read_in_batches(const std::string& bytes, std::size_t batch, const std::string& name) {
  Read out;
  Reader reader(bytes, name, [&](const std::string& w) { out.warnings.push_back(w); });
  glm::dvec3 origin(0.0);
  for (;;) {
    const PointSet b = reader.next(batch);
    if (b.size() == 0) break;
    EXPECT_LE(b.size(), batch);
    if (out.batches++ == 0) origin = b.frame.origin;
    EXPECT_EQ(b.frame.origin, origin) << "every batch in the first's frame";
    out.points.add(b);
  }
  EXPECT_EQ(reader.next(batch).size(), 0u) << "the end stays the end";
  if constexpr (std::is_same_v<Reader, PlyReader>) out.report = reader.report();
  return out;
}

Read read_in_batches(const std::string& bytes, std::size_t batch) {
  return read_in_batches<PlyReader>(bytes, batch, "scan.ply");
}

Read read_whole(const std::string& bytes) {
  Read out;
  const PointSet all = load_ply_from_memory(
      bytes, "scan.ply", &out.report, [&](const std::string& w) { out.warnings.push_back(w); });
  out.points.add(all);
  out.batches = 1;
  return out;
}

TEST(PlyStream, BatchesOfABinaryCloudAreTheWholeRead) {
  const fs::path dir = test::scratch_dir("ply_stream");
  std::string bytes = ply_bytes(scan(20000), dir);
  // x y z as doubles, normals, colours, a radius, the intensity.
  const std::size_t stride = 3 * 8 + 3 * 4 + 3 + 4 + 2;
  spoil(bytes, stride);
  const Read whole = read_whole(bytes);
  ASSERT_EQ(whole.points.at.size(), 19998u);
  ASSERT_EQ(whole.warnings.size(), 2u) << "the dropped points, the normal";
  for (const std::size_t batch : {std::size_t{7}, std::size_t{4096}, std::size_t{1} << 20}) {
    SCOPED_TRACE(batch);
    ASSERT_TRUE(PlyReader(bytes, "scan.ply").streams());
    const Read r = read_in_batches(bytes, batch);
    EXPECT_EQ(r.batches, (20000 + batch - 1) / batch) << "rows of the file a batch";
    EXPECT_TRUE(r.points == whole.points);
    EXPECT_EQ(r.warnings, whole.warnings) << "said once, with the file's totals";
    EXPECT_EQ(r.report.vertices_in_file, 20000u);
    EXPECT_EQ(r.report.dropped_nonfinite, 2u);
    EXPECT_TRUE(r.report.had_normals && r.report.had_colors && r.report.had_radius);
  }
}

// A batch all of whose points are dropped is skipped (none is empty
// before the end); a file none of whose points is usable is refused as
// the whole read refuses it, by the call that reaches its end.
TEST(PlyStream, ABatchOfNoUsablePointIsSkippedAFileOfNoneRefused) {
  const fs::path dir = test::scratch_dir("ply_stream_nan");
  PointSet ps = scan(30);
  for (std::size_t i = 10; i < 20; ++i) ps.positions[i].x = std::nanf("");
  const std::string bytes = ply_bytes(ps, dir);
  const Read r = read_in_batches(bytes, 10);
  EXPECT_EQ(r.batches, 2u);
  EXPECT_TRUE(r.points == read_whole(bytes).points);

  for (glm::vec3& p : ps.positions) p.y = std::nanf("");
  const std::string none = ply_bytes(ps, dir);
  const std::string whole_error = error_of([&] { return load_ply_from_memory(none, "scan.ply"); });
  EXPECT_EQ(whole_error, "scan.ply: no finite points (all 30 vertices are NaN or infinite)");
  EXPECT_EQ(error_of([&] { return PlyReader(none, "scan.ply").next(8); }), whole_error);
}

// What the reader cannot cut is read whole: an ascii file, a mesh, a body
// shorter than its header says (whose warning or error is load_ply's).
TEST(PlyStream, WhatCannotBeCutIsOneBatchOfTheWholeRead) {
  const fs::path dir = test::scratch_dir("ply_stream_whole");
  const std::string ascii =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  const std::string mesh =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  std::string cut = ply_bytes(scan(100), dir);
  cut.resize(cut.size() - 10);
  for (const std::string* bytes : {&ascii, &mesh}) {
    PlyReader reader(*bytes, "m.ply");
    EXPECT_FALSE(reader.streams());
    const PointSet all = reader.next(1);
    EXPECT_EQ(all.size(), 3u) << "one batch, past the batch size";
    EXPECT_EQ(all.triangles.size(), bytes == &mesh ? 1u : 0u);
    EXPECT_EQ(reader.next(1).size(), 0u);
  }
  EXPECT_FALSE(PlyReader(cut, "cut.ply").streams());
  const std::string whole_error = error_of([&] { return load_ply_from_memory(cut, "cut.ply"); });
  EXPECT_FALSE(whole_error.empty());
  EXPECT_EQ(error_of([&] { return PlyReader(cut, "cut.ply").next(10); }), whole_error);
}

// PCD: a binary body is read a batch of records at a time, into the
// points, frame and warnings of one read.
TEST(PcdStream, BatchesOfABinaryCloudAreTheWholeRead) {
  const fs::path dir = test::scratch_dir("pcd_stream");
  PointSet ps = scan(20000);
  ps.radii.clear();
  ps.positions[5].x = ps.positions[6].z = std::nanf("");
  save_pcd(dir / "scan.pcd", ps, PcdData::binary);
  const std::string bytes = test::read_all(dir / "scan.pcd");
  Read whole;
  const PointSet all = load_pcd_from_memory(
      bytes, "scan.pcd", [&](const std::string& w) { whole.warnings.push_back(w); });
  whole.points.add(all);
  ASSERT_EQ(whole.points.at.size(), 19998u);
  ASSERT_EQ(whole.warnings.size(), 1u) << "the dropped points";
  ASSERT_TRUE(PcdReader(bytes, "scan.pcd").streams());
  for (const std::size_t batch : {std::size_t{7}, std::size_t{4096}, std::size_t{1} << 20}) {
    SCOPED_TRACE(batch);
    const Read r = read_in_batches<PcdReader>(bytes, batch, "scan.pcd");
    EXPECT_EQ(r.batches, (20000 + batch - 1) / batch) << "records of the file a batch";
    EXPECT_TRUE(r.points == whole.points);
    EXPECT_EQ(r.warnings, whole.warnings) << "said once, with the file's totals";
  }
}

// Compressed and ascii bodies are read whole; a file of no usable point
// is refused as the whole read refuses it.
TEST(PcdStream, CompressedAndAsciiAreReadWholeAFileOfNoPointRefused) {
  const fs::path dir = test::scratch_dir("pcd_stream_whole");
  PointSet ps = scan(50);
  ps.radii.clear();
  for (const PcdData data : {PcdData::ascii, PcdData::binary_compressed}) {
    save_pcd(dir / "scan.pcd", ps, data);
    const std::string bytes = test::read_all(dir / "scan.pcd");
    PcdReader reader(bytes, "scan.pcd");
    EXPECT_FALSE(reader.streams());
    EXPECT_EQ(reader.next(10).size(), 50u) << "one batch, past the batch size";
    EXPECT_EQ(reader.next(10).size(), 0u);
  }
  for (glm::vec3& p : ps.positions) p.y = std::nanf("");
  save_pcd(dir / "none.pcd", ps, PcdData::binary);
  const std::string none = test::read_all(dir / "none.pcd");
  ASSERT_TRUE(PcdReader(none, "none.pcd").streams());
  const std::string whole_error = error_of([&] { return load_pcd_from_memory(none, "none.pcd"); });
  EXPECT_EQ(whole_error, "none.pcd: no points with a finite position");
  EXPECT_EQ(error_of([&] { return PcdReader(none, "none.pcd").next(8); }), whole_error);
}

}  // namespace
}  // namespace treecut
