// Hierarchy cache: round trip, determinism, and detection of every truncation,
// flipped byte and stale source.
#include "treecut/cache.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>

#include "hierarchy/cache_checksum.hpp"
#include "hierarchy/cache_format.hpp"
#include "hierarchy/cache_layout.hpp"
#include "hierarchy/cache_pages.hpp"
#include "hierarchy/node_arrays.hpp"
#include "test_support.hpp"
#include "treecut/cache_folder.hpp"
#include "treecut/error.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/generate.hpp"

using namespace treecut;
using namespace treecut::tools;
namespace fs = std::filesystem;

namespace {

std::vector<char> read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_all(const fs::path& p, const std::vector<char>& bytes, std::size_t n) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(n));
}

Hierarchy small(std::size_t n = 300) {
  return build_from_points(generate_model(ModelKind::Sphere, n, 4));
}

// A cache as open_model() rewrites it: the same bytes except when the model's
// identity was taken (the header's identity_ns, bytes 80-87 of format 3) and
// so the checksum (the last 8 bytes).
std::vector<char> but_identity_time(std::vector<char> bytes) {
  constexpr std::size_t kIdentityNs = 80;
  if (bytes.size() < kIdentityNs + 16) return bytes;
  std::fill_n(bytes.begin() + kIdentityNs, 8, '\0');
  std::fill_n(bytes.end() - 8, 8, '\0');
  return bytes;
}

// Edits a binary PLY in place: one byte of the first point's x, so the file
// keeps its size but not its content (the caller restores the mtime).
void flip_first_point_byte(const fs::path& ply) {
  std::fstream f(ply, std::ios::in | std::ios::out | std::ios::binary);
  std::string text(4096, '\0');
  f.read(text.data(), static_cast<std::streamsize>(text.size()));
  const auto body = text.find("end_header\n");
  ASSERT_NE(body, std::string::npos);
  f.seekp(static_cast<std::streamoff>(body + 11 + 1));
  f.put(static_cast<char>(text[body + 11 + 1] ^ 0x40));
}

// Writes a generated model to DIR/m.ply; the options open it with its cache
// at DIR/m.tch.
OpenOptions model_in(const fs::path& dir, ModelKind kind, std::size_t points, std::uint64_t seed) {
  save_ply(dir / "m.ply", generate_model(kind, points, seed));
  OpenOptions o;
  o.cache_path = dir / "m.tch";
  return o;
}

bool settled(const CacheKey& k) {
  return k.identity_ns != 0 && k.source_ctime_ns <= k.identity_ns - kSettledNs;
}

// Rewrites CACHE (the model's hierarchy as it is) under KEY: a cache as a
// build that read the model at another moment would have written it.
void rewrite_key(const fs::path& cache, const CacheKey& key) {
  std::string why;
  auto h = load_cache(cache, std::nullopt, &why);
  ASSERT_TRUE(h) << why;
  save_cache(*h, key, cache);
}

}  // namespace

// The paged cache (issue 44) quantizes each page against its own box: a
// center moves by at most half a grid step (under extent / 65534 of its
// page's box, so of the model's), a radius is recomputed around the moved
// children and rounded up (0.14 % a level, under 0.3 % over all the
// levels below, plus the centers' moves); normals, cones, colours, the
// links and counts are
// exact; and a loaded hierarchy saved again is the same, byte for byte and
// value for value.
TEST(Cache, ARoundTripKeepsTheLinksAndMovesNothingPastTheBound) {
  const fs::path dir = test::scratch_dir("cache_roundtrip");
  const Hierarchy h = small(5000);
  const CacheKey key{123, 456, 7};
  save_cache(h, key, dir / "a.tch");
  std::string why;
  auto loaded = load_cache(dir / "a.tch", key, &why);
  ASSERT_TRUE(loaded) << why;
  EXPECT_EQ(loaded->node_count(), h.node_count());
  EXPECT_EQ(loaded->level_count(), h.level_count());
  EXPECT_EQ(check_invariants(*loaded), "");
  const glm::vec3 extent = h.bounds_max() - h.bounds_min();
  const float bound = std::max({extent.x, extent.y, extent.z}) / 65534.0f;
  float worst = 0.0f;
  for (NodeId n = 0; n < h.node_count(); ++n) {
    const glm::vec3 moved = glm::abs(loaded->center(n) - h.center(n));
    worst = std::max({worst, moved.x, moved.y, moved.z});
    ASSERT_NEAR(loaded->radius(n), h.radius(n),
                0.003f * h.radius(n) + 2.0f * float(h.level_count()) * bound)
        << n;
    if (h.is_leaf(n)) {
      ASSERT_GE(loaded->radius(n), h.radius(n)) << n;
    }
    ASSERT_EQ(loaded->arrays().normal_cone[n], h.arrays().normal_cone[n]);
    ASSERT_EQ(loaded->arrays().color[n], h.arrays().color[n]);
    ASSERT_NEAR(loaded->arrays().priority[n], h.arrays().priority[n], 0.5f / 4095.0f);
    ASSERT_EQ(loaded->arrays().first_child[n], h.arrays().first_child[n]);
    ASSERT_EQ(loaded->arrays().parent[n], h.arrays().parent[n]);
    ASSERT_EQ(loaded->arrays().point_count[n], h.arrays().point_count[n]);
  }
  EXPECT_LE(worst, bound);
  EXPECT_GT(worst, 0.0f) << "quantized at all";

  save_cache(*loaded, key, dir / "b.tch");
  EXPECT_EQ(read_all(dir / "a.tch"), read_all(dir / "b.tch")) << "a loaded cache saves the same";
  auto again = load_cache(dir / "b.tch", key, &why);
  ASSERT_TRUE(again) << why;
  for (NodeId n = 0; n < h.node_count(); ++n) {
    ASSERT_EQ(again->arrays().center_radius[n], loaded->arrays().center_radius[n]);
    ASSERT_EQ(again->arrays().splat_radius[n], loaded->arrays().splat_radius[n]);
  }
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().extension(), ".tch") << "temporary left behind: " << e.path();
}

// The model's CoordinateFrame (issue 29): a map origin, the format's z-up
// and the coordinate system's text come back from the cache as they went in;
// every truncation and flipped byte of such a cache is caught as before.
TEST(Cache, TheCoordinateFrameRoundTrips) {
  const fs::path dir = test::scratch_dir("cache_frame");
  PointSet p = generate_model(ModelKind::Sphere, 3000, 2);
  p.frame.origin = glm::dvec3(500000.25, 5000000.5, -12.0);
  p.frame.z_up = true;
  p.frame.crs = "WKT: PROJCS[\"WGS 84 / UTM zone 33N\"]";
  const Hierarchy h = build_from_points(std::move(p));
  EXPECT_EQ(h.frame().origin, glm::dvec3(500000.25, 5000000.5, -12.0));
  save_cache(h, {1, 2, 3}, dir / "f.tch");
  std::string why;
  auto loaded = load_cache(dir / "f.tch", std::nullopt, &why);
  ASSERT_TRUE(loaded) << why;
  EXPECT_EQ(loaded->frame().origin, h.frame().origin);
  EXPECT_TRUE(loaded->frame().z_up);
  EXPECT_EQ(loaded->frame().crs, h.frame().crs);
  const std::vector<char> raw = read_all(dir / "f.tch");
  const std::string bytes(raw.begin(), raw.end());
  for (std::size_t cut = 0; cut < bytes.size(); cut += 97) {
    std::ofstream(dir / "t.tch", std::ios::binary | std::ios::trunc) << bytes.substr(0, cut);
    EXPECT_FALSE(load_cache(dir / "t.tch", std::nullopt, &why)) << cut;
  }
  // The crs text is inside the checksum: a flipped byte there is caught.
  const std::size_t at = bytes.find("UTM zone");
  ASSERT_NE(at, std::string::npos);
  std::string flipped = bytes;
  flipped[at] ^= 0x20;
  std::ofstream(dir / "t.tch", std::ios::binary | std::ios::trunc) << flipped;
  EXPECT_FALSE(load_cache(dir / "t.tch", std::nullopt, &why));
  EXPECT_NE(why.find("checksum"), std::string::npos) << why;
}

// The file's attributes per node (issue 29): names, kinds, offsets, ranges
// and every value come back as they went in; a flipped value is caught.
TEST(Cache, TheAttributesRoundTrip) {
  const fs::path dir = test::scratch_dir("cache_attributes");
  PointSet p = generate_model(ModelKind::Sphere, 3000, 2);
  PointAttribute time{.name = "gps_time", .kind = AttributeKind::measure, .offset = 3.0e8};
  PointAttribute cls{.name = "classification", .kind = AttributeKind::category, .offset = 0.0};
  for (std::size_t i = 0; i < p.size(); ++i) {
    time.values.push_back(0.01f * float(i));
    cls.values.push_back(p.positions[i].z > 0 ? 6.0f : 2.0f);
  }
  p.attributes = {time, cls};
  const Hierarchy h = build_from_points(std::move(p));
  ASSERT_EQ(h.attributes().size(), 2u);
  save_cache(h, {1, 2, 3}, dir / "a.tch");
  std::string why;
  auto loaded = load_cache(dir / "a.tch", std::nullopt, &why);
  ASSERT_TRUE(loaded) << why;
  ASSERT_EQ(loaded->attributes().size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    const NodeAttribute &a = h.attributes()[k], &b = loaded->attributes()[k];
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.kind, a.kind);
    EXPECT_EQ(b.offset, a.offset);
    EXPECT_EQ(b.min, a.min);
    EXPECT_EQ(b.max, a.max);
    ASSERT_EQ(b.values.size(), a.values.size());
    EXPECT_TRUE(std::equal(a.values.begin(), a.values.end(), b.values.begin()));
  }
  EXPECT_EQ(loaded->memory_bytes(), h.memory_bytes());
  auto bytes = read_all(dir / "a.tch");
  bytes[bytes.size() - 8 - 4] ^= 0x10;  // the last attribute value
  write_all(dir / "b.tch", bytes, bytes.size());
  EXPECT_FALSE(load_cache(dir / "b.tch", std::nullopt, &why));
}

// Each page has its own checksum (issue 44): a byte flipped inside one is
// refused naming that page, so a reader of one page knows which; a byte of
// the meta part (header, page table, records) is the file's checksum's.
// A build's hierarchy is quantized in place as its image is made (no
// decoding): value for value what the image's file loads as.
TEST(Cache, ABuildQuantizedInPlaceIsWhatItsCacheLoadsAs) {
  PointSet p = generate_model(ModelKind::City, 20000, 5);
  tools::add_survey_attributes(p, ModelKind::City);
  const CacheImage image(build_from_points(std::move(p)), {1, 2, 3});
  const Hierarchy& built = image.hierarchy();
  const fs::path file = test::scratch_dir("cache_in_place") / "a.tch";
  image.save(file);
  std::string why;
  const std::optional<Hierarchy> read = load_cache(file, std::nullopt, &why);
  ASSERT_TRUE(read) << why;
  const Hierarchy& loaded = *read;
  ASSERT_EQ(loaded.node_count(), built.node_count());
  EXPECT_EQ(check_invariants(built), "");
  const HierarchyArrays &a = built.arrays(), &b = loaded.arrays();
  for (NodeId n = 0; n < built.node_count(); ++n) {
    ASSERT_EQ(a.center_radius[n], b.center_radius[n]) << n;
    ASSERT_EQ(a.splat_radius[n], b.splat_radius[n]) << n;
    ASSERT_EQ(a.normal_cone[n], b.normal_cone[n]) << n;
    ASSERT_EQ(a.color[n], b.color[n]) << n;
    ASSERT_EQ(a.priority[n], b.priority[n]) << n;
    ASSERT_EQ(a.first_child[n], b.first_child[n]) << n;
    ASSERT_EQ(a.parent[n], b.parent[n]) << n;
    ASSERT_EQ(a.point_count[n], b.point_count[n]) << n;
    ASSERT_EQ(a.depth[n], b.depth[n]) << n;
  }
  ASSERT_EQ(built.attributes().size(), loaded.attributes().size());
  for (std::size_t k = 0; k < built.attributes().size(); ++k) {
    const NodeAttribute &x = built.attributes()[k], &y = loaded.attributes()[k];
    ASSERT_EQ(x.values.size(), y.values.size());
    EXPECT_TRUE(std::equal(x.values.begin(), x.values.end(), y.values.begin(),
                           [](float u, float v) { return std::memcmp(&u, &v, 4) == 0; }))
        << x.name;
  }
}

// Every page decodes alone (issue 45: drawing pages as they arrive): from
// the page table and links, into arrays of the whole, it writes its own
// nodes, exactly as the whole load has them, and no other.
TEST(Cache, EachPageDecodesAloneAsTheWholeLoadsIt) {
  const fs::path dir = test::scratch_dir("cache_page_alone");
  save_cache(small(20000), {1, 2, 3}, dir / "a.tch");
  std::string why;
  const std::optional<Hierarchy> whole = load_cache(dir / "a.tch", std::nullopt, &why);
  ASSERT_TRUE(whole) << why;
  const std::optional<detail::CacheOutline> outline =
      detail::read_cache_outline(detail::FileSource(dir / "a.tch"), &why);
  ASSERT_TRUE(outline) << why;
  const cache_pages::PageIndex* index = &outline->index;
  ASSERT_GT(index->pages(), 2u);
  const std::vector<char> file = read_all(dir / "a.tch");
  const cache_pages::PageSource source = [&](const cache_layout::PageRecord& r,
                                             std::vector<unsigned char>& buffer) {
    buffer.assign(file.begin() + static_cast<std::ptrdiff_t>(r.offset),
                  file.begin() + static_cast<std::ptrdiff_t>(r.offset + r.bytes));
    return static_cast<const unsigned char*>(buffer.data());
  };
  const std::size_t n = whole->node_count();
  const HierarchyArrays& a = whole->arrays();
  std::uint64_t written_total = 0;
  for (std::uint32_t p = 0; p < index->pages(); ++p) {
    detail::NodeArrays o;  // every value a sentinel no page writes
    o.center_radius.assign(n, glm::vec4(-1.0f)), o.splat_radius.assign(n, -1.0f);
    o.normal_cone.assign(n, glm::i16vec4(7)), o.color.assign(n, glm::u8vec4(7));
    o.priority.assign(n, -1.0f), o.point_count.assign(n, 0), o.parent.assign(n, 7);
    o.first_child.assign(n, 7), o.child_count.assign(n, 7), o.depth.assign(n, 255);
    const cache_pages::NodeSink sink{o.center_radius.data(),
                                     o.splat_radius.data(),
                                     o.normal_cone.data(),
                                     o.color.data(),
                                     o.priority.data(),
                                     o.point_count.data(),
                                     o.parent.data(),
                                     o.first_child.data(),
                                     o.child_count.data(),
                                     o.depth.data(),
                                     {}};
    std::vector<unsigned char> raw;
    ASSERT_EQ(cache_pages::decode_page(*index, p, source, sink, raw), "") << "page " << p;
    std::vector<bool> mine(n, false);
    for (const cache_layout::PageRun& run : index->links().runs_of(p))
      for (std::uint64_t i = run.first; i < run.first + run.count; ++i) mine[i] = true;
    for (NodeId i = 0; i < n; ++i) {
      if (!mine[i]) {
        ASSERT_EQ(o.point_count[i], 0u) << "page " << p << " wrote node " << i;
        ASSERT_EQ(o.depth[i], 255) << "page " << p << " wrote node " << i;
        continue;
      }
      ++written_total;
      ASSERT_EQ(test::node_difference(a, o.spans(), i), "") << "page " << p << ", node " << i;
    }
  }
  EXPECT_EQ(written_total, n) << "the pages hold every node once";
}

// The links are under the meta part's checksum, and checked beyond it: a
// forged run table (ids two pages claim) is refused with a reason.
TEST(Cache, PagesWhoseRunsOverlapAreRefused) {
  const fs::path dir = test::scratch_dir("cache_runs");
  save_cache(small(20000), {1, 2, 3}, dir / "a.tch");
  std::vector<char> bytes = read_all(dir / "a.tch");
  cache_layout::Header h;
  std::memcpy(&h, bytes.data(), sizeof h);
  const auto at = cache_layout::PageLinksAt::after(h.page_table, h.page_count, h.level_count);
  cache_layout::PageRun run;  // the last page's first run, one id earlier
  std::uint64_t first_run;
  std::memcpy(&first_run, bytes.data() + at.run_index + 8 * (h.page_count - 1), 8);
  char* where = bytes.data() + at.runs + first_run * sizeof run;
  std::memcpy(&run, where, sizeof run);
  --run.first;
  std::memcpy(where, &run, sizeof run);
  ASSERT_TRUE(detail::reseal_cache(reinterpret_cast<unsigned char*>(bytes.data()), bytes.size()));
  write_all(dir / "b.tch", bytes, bytes.size());
  std::string why;
  EXPECT_FALSE(load_cache(dir / "b.tch", std::nullopt, &why));
  EXPECT_TRUE(why.find("runs") != std::string::npos || why.find("overlap") != std::string::npos)
      << why;
}

TEST(Cache, ACorruptedPageIsNamedByItsNumber) {
  const fs::path dir = test::scratch_dir("cache_page");
  save_cache(small(20000), {1, 2, 3}, dir / "a.tch");
  std::vector<char> bytes = read_all(dir / "a.tch");
  auto why_with = [&](std::size_t at) {
    bytes[at] ^= 0x08;
    write_all(dir / "b.tch", bytes, bytes.size());
    bytes[at] ^= 0x08;
    std::string why;
    EXPECT_FALSE(load_cache(dir / "b.tch", std::nullopt, &why)) << "byte " << at;
    return why;
  };
  // The table alone: every node in a page, the pages under their parents.
  std::string why;
  const auto pages = read_cache_pages(dir / "a.tch", &why);
  ASSERT_TRUE(pages) << why;
  std::uint64_t nodes = 0, bytes_in_pages = 0;
  for (std::size_t p = 0; p < pages->size(); ++p) {
    const CachePage& page = (*pages)[p];
    nodes += page.nodes, bytes_in_pages += page.bytes;
    EXPECT_LE(page.nodes, 8192u);
    if (p > 0) {
      EXPECT_LT(page.parent_page, p);
    }
  }
  EXPECT_EQ(nodes, small(20000).node_count());
  EXPECT_LT(bytes_in_pages, bytes.size());
  const std::string last = why_with(bytes.size() - 9);  // the last page's last byte
  EXPECT_EQ(last.rfind("page ", 0), 0u) << last;
  EXPECT_NE(last.find(" of "), std::string::npos) << last;
  EXPECT_NE(last.find("checksum mismatch (corrupted)"), std::string::npos) << last;
  const int page = std::stoi(last.substr(5)), count = std::stoi(last.substr(last.find(" of ") + 4));
  EXPECT_GT(count, 1) << "20,000 points make several pages of 8,192 nodes at most";
  EXPECT_EQ(page, count - 1);
  EXPECT_EQ(static_cast<std::size_t>(count), pages->size());
  // A page's damage is the page's: the table still reads alone.
  bytes[bytes.size() - 9] ^= 0x08;
  write_all(dir / "b.tch", bytes, bytes.size());
  bytes[bytes.size() - 9] ^= 0x08;
  EXPECT_TRUE(read_cache_pages(dir / "b.tch", &why)) << why;
  EXPECT_EQ(why_with(40), "checksum mismatch (corrupted)");  // the header's page count
  EXPECT_FALSE(read_cache_pages(dir / "b.tch", &why));
}

TEST(Cache, SameInputGivesAByteIdenticalFile) {
  const fs::path dir = test::scratch_dir("cache_deterministic");
  BuildOptions one, two;
  one.threads = 1;
  two.threads = 3;
  save_cache(build_from_points(generate_model(ModelKind::Terrain, 20000, 2), {}, one), {1, 2, 3},
             dir / "a.tch");
  save_cache(build_from_points(generate_model(ModelKind::Terrain, 20000, 2), {}, two), {1, 2, 3},
             dir / "b.tch");
  EXPECT_EQ(read_all(dir / "a.tch"), read_all(dir / "b.tch"));
}

TEST(Cache, EveryTruncationIsDetected) {
  const fs::path dir = test::scratch_dir("cache_truncate");
  save_cache(small(), {1, 2, 3}, dir / "full.tch");
  const auto bytes = read_all(dir / "full.tch");
  for (std::size_t len = 0; len < bytes.size(); ++len) {
    write_all(dir / "cut.tch", bytes, len);
    std::string why;
    ASSERT_FALSE(load_cache(dir / "cut.tch", std::nullopt, &why)) << "length " << len;
    ASSERT_FALSE(why.empty());
  }
}

TEST(Cache, EverySingleFlippedByteIsDetected) {
  const fs::path dir = test::scratch_dir("cache_flip");
  save_cache(small(200), {1, 2, 3}, dir / "full.tch");
  auto bytes = read_all(dir / "full.tch");
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    for (unsigned char mask : {0x01, 0x80}) {
      bytes[i] = static_cast<char>(bytes[i] ^ mask);
      write_all(dir / "flip.tch", bytes, bytes.size());
      bytes[i] = static_cast<char>(bytes[i] ^ mask);
      ASSERT_FALSE(load_cache(dir / "flip.tch", std::nullopt, nullptr)) << "byte " << i;
    }
  }
}

TEST(Cache, StaleKeyIsRejected) {
  const fs::path dir = test::scratch_dir("cache_stale");
  save_cache(small(), {10, 20, 0}, dir / "a.tch");
  std::string why;
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{11, 20, 0}, &why));
  EXPECT_NE(why.find("stale"), std::string::npos);
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{10, 20, 1}, &why)) << "other build options";
  EXPECT_TRUE(load_cache(dir / "a.tch", CacheKey{10, 20, 0}, &why));
}

TEST(Cache, StaleWhenTheContentHashDiffers) {
  const fs::path dir = test::scratch_dir("cache_stale_hash");
  save_cache(small(), {10, 20, 0, 0x1234}, dir / "a.tch");
  std::string why;
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{10, 20, 0, 0x1235}, &why));
  EXPECT_NE(why.find("stale"), std::string::npos) << why;
  EXPECT_TRUE(load_cache(dir / "a.tch", CacheKey{10, 99, 0, 0x1234}, &why))
      << "another mtime, the same content: " << why;
  const auto key = read_cache_key(dir / "a.tch", &why);
  ASSERT_TRUE(key) << why;
  EXPECT_EQ(key->content_hash, 0x1234u);
  EXPECT_EQ(key->source_mtime_ns, 20);
}

// A model edited in place (same size) with its modification time restored, as
// `touch -d` or a careful editor does: the content hash notices.
TEST(Cache, AModelEditedInPlaceWithItsMtimeRestoredIsRebuilt) {
  const fs::path dir = test::scratch_dir("cache_edit_in_place");
  OpenOptions o = model_in(dir, ModelKind::Terrain, 4000, 3);
  const OpenedModel first = open_model(dir / "m.ply", o);
  ASSERT_FALSE(first.from_cache);
  ASSERT_TRUE(open_model(dir / "m.ply", o).from_cache);
  const auto size = fs::file_size(dir / "m.ply");
  const auto mtime = fs::last_write_time(dir / "m.ply");
  ASSERT_NO_FATAL_FAILURE(flip_first_point_byte(dir / "m.ply"));
  fs::last_write_time(dir / "m.ply", mtime);
  ASSERT_EQ(fs::file_size(dir / "m.ply"), size);
  ASSERT_EQ(fs::last_write_time(dir / "m.ply"), mtime);
  const OpenedModel edited = open_model(dir / "m.ply", o);
  EXPECT_FALSE(edited.from_cache) << "served a cache built from other content";
  EXPECT_NE(edited.cache_note.find("stale"), std::string::npos) << edited.cache_note;
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache) << "the rebuilt cache was written back";
}

TEST(Cache, TheIdentityServesOnlyWhenExactAndSettled) {
  CacheKey stored{100, 5'000'000'000, 7, 0x1234, 42, 99, 6'000'000'000, 0};
  stored.identity_ns = stored.source_ctime_ns + kSettledNs;
  EXPECT_TRUE(cache_identity_serves(stored, stored));
  CacheKey now = stored;
  now.content_hash = 0;  // not read: the identity alone decides
  now.identity_ns += 3'600'000'000'000;
  EXPECT_TRUE(cache_identity_serves(stored, now));
  auto differs = [&](auto change) {
    CacheKey other = now;
    change(other);
    return !cache_identity_serves(stored, other);
  };
  EXPECT_TRUE(differs([](CacheKey& k) { k.source_device ^= 1; }));
  EXPECT_TRUE(differs([](CacheKey& k) { k.source_inode ^= 1; }));
  EXPECT_TRUE(differs([](CacheKey& k) { k.source_size ^= 1; }));
  EXPECT_TRUE(differs([](CacheKey& k) { k.source_mtime_ns += 1; }));
  EXPECT_TRUE(differs([](CacheKey& k) { k.source_ctime_ns += 1; }));
  EXPECT_TRUE(differs([](CacheKey& k) { k.options_bits ^= 1; }));
  CacheKey racy = stored;  // the build read the model 1 ns less than 2 s after its change
  racy.identity_ns -= 1;
  EXPECT_FALSE(cache_identity_serves(racy, racy));
  CacheKey unknown = stored;
  unknown.identity_ns = 0;
  unknown.source_ctime_ns = -kSettledNs;
  EXPECT_FALSE(cache_identity_serves(unknown, unknown));
}

// The fast path: a cache whose model's identity is exactly the recorded one,
// recorded at least 2 s after the model's last change, is served without
// reading the model. The stored hash is made wrong on purpose: a hash would
// reject it.
TEST(Cache, AnUnchangedSettledModelIsServedWithoutHashing) {
  const fs::path dir = test::scratch_dir("cache_identity_fast");
  OpenOptions o = model_in(dir, ModelKind::Terrain, 4000, 3);
  const OpenedModel built = open_model(dir / "m.ply", o);
  ASSERT_TRUE(built.hashed);
  CacheKey key = cache_key_for(dir / "m.ply", options_bits(o.attributes, o.build));
  key.identity_ns = key.source_ctime_ns + kSettledNs;  // read 2 s after its last change
  key.content_hash = ~key.content_hash;
  rewrite_key(dir / "m.tch", key);
  const OpenedModel fast = open_model(dir / "m.ply", o);
  EXPECT_TRUE(fast.from_cache) << fast.cache_note;
  EXPECT_FALSE(fast.hashed);
  EXPECT_EQ(fast.hash_seconds, 0.0);
  EXPECT_EQ(fast.hierarchy.node_count(), built.hierarchy.node_count());

  // A touch moves the identity: the content decides, and here the stored hash
  // is not the model's, so the cache is rebuilt.
  fs::last_write_time(dir / "m.ply", fs::last_write_time(dir / "m.ply") + std::chrono::seconds(5));
  const OpenedModel touched = open_model(dir / "m.ply", o);
  EXPECT_TRUE(touched.hashed);
  EXPECT_FALSE(touched.from_cache);
  EXPECT_NE(touched.cache_note.find("stale"), std::string::npos) << touched.cache_note;
}

// What a file system with coarse timestamps can do: an edit in place (mtime
// restored) right after the build's read, in the same timestamp tick, leaves
// the identity exactly as recorded. The recorded ctime was then less than 2 s
// older than the read, so the content is hashed and the cache rebuilt.
TEST(Cache, AnEditInTheTickOfTheBuildIsHashedAndRebuilt) {
  const fs::path dir = test::scratch_dir("cache_identity_racy");
  OpenOptions o = model_in(dir, ModelKind::Terrain, 4000, 3);
  ASSERT_FALSE(open_model(dir / "m.ply", o).from_cache);
  std::string why;
  const auto built_for = read_cache_key(dir / "m.tch", &why);
  ASSERT_TRUE(built_for) << why;
  const auto mtime = fs::last_write_time(dir / "m.ply");
  ASSERT_NO_FATAL_FAILURE(flip_first_point_byte(dir / "m.ply"));
  fs::last_write_time(dir / "m.ply", mtime);
  // The edited file's identity, recorded with the old content's hash, 1 s after its ctime.
  CacheKey hidden = cache_identity_of(dir / "m.ply", options_bits(o.attributes, o.build));
  hidden.content_hash = built_for->content_hash;
  hidden.identity_ns = hidden.source_ctime_ns + kSettledNs / 2;
  rewrite_key(dir / "m.tch", hidden);
  const OpenedModel edited = open_model(dir / "m.ply", o);
  EXPECT_TRUE(edited.hashed);
  EXPECT_FALSE(edited.from_cache) << "served a cache built from other content";
  EXPECT_NE(edited.cache_note.find("stale"), std::string::npos) << edited.cache_note;
  const auto rebuilt = read_cache_key(dir / "m.tch", &why);
  ASSERT_TRUE(rebuilt) << why;
  EXPECT_NE(rebuilt->content_hash, built_for->content_hash);
  EXPECT_EQ(rebuilt->content_hash, content_hash_of(dir / "m.ply"));
}

// A build right after the model was written (ctime within 2 s of the read)
// is not settled: the next open hashes, and the same content serves.
TEST(Cache, AFreshBuildIsCheckedByItsHashUntilSettled) {
  const fs::path dir = test::scratch_dir("cache_identity_fresh");
  OpenOptions o = model_in(dir, ModelKind::City, 3000, 1);
  ASSERT_FALSE(open_model(dir / "m.ply", o).from_cache);
  std::string why;
  const auto stored = read_cache_key(dir / "m.tch", &why);
  ASSERT_TRUE(stored) << why;
  EXPECT_EQ(stored->source_inode, cache_identity_of(dir / "m.ply", 0).source_inode);
  const OpenedModel again = open_model(dir / "m.ply", o);
  EXPECT_TRUE(again.from_cache) << again.cache_note;
  // Decided by what was recorded, not by how long this test took.
  EXPECT_EQ(again.hashed, !settled(*stored));
}

// Only touched: the identity moves, the content is hashed, the same hash serves.
TEST(Cache, ATouchedModelIsHashedAndServed) {
  const fs::path dir = test::scratch_dir("cache_identity_touch");
  OpenOptions o = model_in(dir, ModelKind::City, 3000, 1);
  ASSERT_FALSE(open_model(dir / "m.ply", o).from_cache);
  std::string why;
  const auto before = read_cache_key(dir / "m.tch", &why);
  ASSERT_TRUE(before) << why;
  fs::last_write_time(dir / "m.ply", fs::last_write_time(dir / "m.ply") - std::chrono::hours(1));
  const OpenedModel touched = open_model(dir / "m.ply", o);
  EXPECT_TRUE(touched.hashed);
  EXPECT_TRUE(touched.from_cache) << touched.cache_note;
  EXPECT_EQ(content_hash_of(dir / "m.ply"), before->content_hash);
}

// A model whose last change is long past (a shared asset): its first build is
// settled, so the next open reads nothing of it; after a touch-like identity
// change the hash serves and the cache is rewritten with the identity of now.
TEST(Cache, ASettledModelSkipsTheHashAndASettledHashRefreshesTheIdentity) {
  TREECUT_REQUIRE_ASSET(bunny, "bun_zipper.ply");
  const fs::path dir = test::scratch_dir("cache_identity_refresh");
  OpenOptions o;
  o.cache_path = dir / "bunny.tch";
  const OpenedModel built = open_model(bunny, o);
  ASSERT_TRUE(built.hashed);
  std::string why;
  const auto stored = read_cache_key(dir / "bunny.tch", &why);
  ASSERT_TRUE(stored) << why;
  if (!settled(*stored)) GTEST_SKIP() << bunny << " changed less than 2 s before it was read";
  const OpenedModel fast = open_model(bunny, o);
  EXPECT_TRUE(fast.from_cache);
  EXPECT_FALSE(fast.hashed);

  CacheKey moved = *stored;  // as if the model had been touched since
  moved.source_mtime_ns -= 1;
  rewrite_key(dir / "bunny.tch", moved);
  const OpenedModel hashed = open_model(bunny, o);
  EXPECT_TRUE(hashed.from_cache) << hashed.cache_note;
  EXPECT_TRUE(hashed.hashed);
  EXPECT_TRUE(hashed.cache_refreshed);
  const OpenedModel refreshed = open_model(bunny, o);
  EXPECT_TRUE(refreshed.from_cache);
  EXPECT_FALSE(refreshed.hashed) << "the refreshed identity serves";
}

TEST(Cache, ContentHashIsOfTheBytes) {
  const fs::path dir = test::scratch_dir("cache_content_hash");
  std::ofstream(dir / "a") << "same bytes";
  std::ofstream(dir / "b") << "same bytes";
  std::ofstream(dir / "c") << "same bytez";
  EXPECT_EQ(content_hash_of(dir / "a"), content_hash_of(dir / "b"));
  EXPECT_NE(content_hash_of(dir / "a"), content_hash_of(dir / "c"));
  std::ofstream(dir / "empty");
  EXPECT_NO_THROW(content_hash_of(dir / "empty"));
  EXPECT_THROW(content_hash_of(dir / "missing"), InputError);
  EXPECT_THROW(content_hash_of(dir), InputError) << "a directory";
}

// Issue 29: rounding stays under 1 mm within 32,768 units of the model's
// origin (a float's spacing there is 2^-9); a model reaching further is
// read with one warning naming the spacing, one within it with none. The
// origin is the centre of the points' bounds (issue 43), so a model 64 km
// across stays within it.
TEST(Cache, PointsPastTheFloatBoundAreNamedInAWarning) {
  const fs::path dir = test::scratch_dir("cache_float_bound");
  for (const double far : {64000.0, 70000.0}) {
    std::ofstream text(dir / "cloud.xyz");
    text.precision(10);
    for (int i = 0; i < 64; ++i) text << 500000.0 + 0.1 * (i % 8) << " 0 " << 0.1 * (i / 8) << "\n";
    text << 500000.0 + far << " 0 0\n";
    text.close();
    OpenOptions o;
    o.use_cache = false;
    std::vector<std::string> warnings;
    o.warn = [&](const std::string& w) { warnings.push_back(w); };
    const OpenedModel m = open_model(dir / "cloud.xyz", o);
    EXPECT_EQ(m.hierarchy.frame().origin.x, 500000.0 + far / 2);
    const auto named = std::count_if(warnings.begin(), warnings.end(), [](const std::string& w) {
      return w.find("from the model's origin: as floats their spacing there is 0.00391") !=
             std::string::npos;
    });
    EXPECT_EQ(named, far / 2 > 32768.0 ? 1 : 0) << far;
  }
}

// Issue 30: the default cache folder stays under TREECUT_CACHE_LIMIT by
// removing the least recently used caches, never the one just written;
// opening a cache marks it used; nothing but a cache is listed or removed.
TEST(CacheFolder, TheLeastRecentlyUsedCachesGoPastTheLimit) {
  const fs::path dir = test::scratch_dir("cache_folder_lru");
  const fs::path folder = dir / "xdg" / "treecut";
  const char* xdg_before = std::getenv("XDG_CACHE_HOME");
  const std::optional<std::string> restore =
      xdg_before ? std::optional<std::string>(xdg_before) : std::nullopt;
  ASSERT_EQ(setenv("XDG_CACHE_HOME", (dir / "xdg").c_str(), 1), 0);
  EXPECT_EQ(default_cache_folder(), folder);
  for (const char* name : {"a", "b", "c"}) {
    save_ply(dir / (std::string(name) + ".ply"), generate_model(ModelKind::Sphere, 3000, 1));
  }
  OpenOptions o;
  std::vector<std::string> warnings;
  o.warn = [&](const std::string& w) { warnings.push_back(w); };
  const fs::path a = open_model(dir / "a.ply", o).cache, b = open_model(dir / "b.ply", o).cache;
  const auto now = fs::file_time_type::clock::now();
  fs::last_write_time(a, now - std::chrono::hours(2));
  fs::last_write_time(b, now - std::chrono::hours(1));
  ASSERT_TRUE(open_model(dir / "a.ply", o).from_cache);
  EXPECT_GT(fs::last_write_time(a), now - std::chrono::minutes(1)) << "opening marked it used";
  fs::last_write_time(a, now - std::chrono::minutes(10));  // after b, before c
  std::ofstream(folder / "notes.tch") << "the user's own file\n";
  const std::uint64_t one = fs::file_size(a);
  ASSERT_EQ(setenv("TREECUT_CACHE_LIMIT", std::to_string(2 * one + one / 2).c_str(), 1), 0);
  warnings.clear();
  const fs::path c = open_model(dir / "c.ply", o).cache;
  std::vector<fs::path> left;
  for (const CacheFileInfo& info : list_caches(folder)) left.push_back(info.file);
  EXPECT_EQ(left, (std::vector<fs::path>{c, a})) << "b was the least recently used";
  EXPECT_TRUE(fs::exists(folder / "notes.tch"));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("removed 1 least recently used cache(s)"), std::string::npos)
      << warnings[0];
  // Removing every cache leaves the user's file.
  EXPECT_TRUE(remove_caches(list_caches(folder)).empty());
  EXPECT_TRUE(list_caches(folder).empty());
  EXPECT_TRUE(fs::exists(folder / "notes.tch"));
  ASSERT_EQ(setenv("TREECUT_CACHE_LIMIT", "lots", 1), 0);
  EXPECT_THROW((void)cache_size_limit(), InputError);
  unsetenv("TREECUT_CACHE_LIMIT");
  if (restore) {
    setenv("XDG_CACHE_HOME", restore->c_str(), 1);
  } else {
    unsetenv("XDG_CACHE_HOME");
  }
  EXPECT_EQ(parse_byte_size("1.5G"), std::uint64_t{3} << 29);
  EXPECT_EQ(parse_byte_size("200M"), std::uint64_t{200} << 20);
  EXPECT_EQ(parse_byte_size("4096"), 4096u);
  EXPECT_EQ(parse_byte_size("2GiB"), std::uint64_t{2} << 30);
  EXPECT_FALSE(parse_byte_size("-1"));
  EXPECT_FALSE(parse_byte_size("5X"));
  EXPECT_FALSE(parse_byte_size(""));
}

TEST(Cache, OpenModelUsesTheCacheAndRebuildsACorruptOne) {
  const fs::path dir = test::scratch_dir("cache_open");
  OpenOptions o = model_in(dir, ModelKind::City, 3000, 1);
  std::vector<std::string> warnings;
  o.warn = [&](const std::string& w) { warnings.push_back(w); };

  const OpenedModel first = open_model(dir / "m.ply", o);
  EXPECT_FALSE(first.from_cache);
  const OpenedModel second = open_model(dir / "m.ply", o);
  EXPECT_TRUE(second.from_cache) << "the second load skips the build";
  EXPECT_EQ(second.hierarchy.node_count(), first.hierarchy.node_count());

  auto bytes = read_all(dir / "m.tch");
  bytes[bytes.size() / 2] ^= 0x10;
  write_all(dir / "m.tch", bytes, bytes.size());
  const OpenedModel third = open_model(dir / "m.ply", o);
  EXPECT_FALSE(third.from_cache);
  EXPECT_NE(third.cache_note.find("checksum"), std::string::npos) << third.cache_note;
  ASSERT_FALSE(warnings.empty());
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache) << "the rebuilt cache was written back";

  // The content decides, not the modification time: a touch keeps the cache...
  fs::last_write_time(dir / "m.ply", fs::last_write_time(dir / "m.ply") + std::chrono::seconds(5));
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache) << "only the mtime changed";
  // ...and other content of the same size makes it stale.
  save_ply(dir / "m.ply", generate_model(ModelKind::City, 3000, 2));
  const OpenedModel fourth = open_model(dir / "m.ply", o);
  EXPECT_FALSE(fourth.from_cache);
  EXPECT_NE(fourth.cache_note.find("stale"), std::string::npos);

  // A cache file opened directly.
  const OpenedModel direct = open_model(dir / "m.tch", o);
  EXPECT_TRUE(direct.from_cache);
  EXPECT_EQ(direct.hierarchy.node_count(), first.hierarchy.node_count());
}

// End to end: whatever prefix of its cache survives, open_model() notices,
// says why, rebuilds from the PLY and writes the complete cache back.
TEST(Cache, OpenModelRebuildsFromThePlyAfterEveryTruncationOfItsCache) {
  const fs::path dir = test::scratch_dir("cache_open_truncate");
  OpenOptions o = model_in(dir, ModelKind::Sphere, 24, 5);
  std::size_t rebuild_warnings = 0;
  o.warn = [&](const std::string& w) {
    rebuild_warnings += w.find("rebuilding") != std::string::npos;
  };
  const OpenedModel built = open_model(dir / "m.ply", o);
  ASSERT_FALSE(built.from_cache);
  const auto bytes = read_all(dir / "m.tch");
  ASSERT_FALSE(bytes.empty());
  for (std::size_t len = 0; len < bytes.size(); ++len) {
    write_all(dir / "m.tch", bytes, len);
    const OpenedModel m = open_model(dir / "m.ply", o);
    ASSERT_FALSE(m.from_cache) << "length " << len;
    ASSERT_FALSE(m.cache_note.empty()) << "length " << len;
    ASSERT_EQ(m.hierarchy.node_count(), built.hierarchy.node_count());
    ASSERT_EQ(but_identity_time(read_all(dir / "m.tch")), but_identity_time(bytes))
        << "length " << len << ": not rewritten";
  }
  EXPECT_EQ(rebuild_warnings, bytes.size());
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache);
}

TEST(Cache, OpenModelRebuildsFromThePlyAfterAnyFlippedByteInItsCache) {
  const fs::path dir = test::scratch_dir("cache_open_flip");
  OpenOptions o = model_in(dir, ModelKind::Terrain, 24, 5);
  const OpenedModel built = open_model(dir / "m.ply", o);
  auto bytes = read_all(dir / "m.tch");
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    bytes[i] = static_cast<char>(bytes[i] ^ 0x04);
    write_all(dir / "m.tch", bytes, bytes.size());
    bytes[i] = static_cast<char>(bytes[i] ^ 0x04);
    const OpenedModel m = open_model(dir / "m.ply", o);
    ASSERT_FALSE(m.from_cache) << "byte " << i;
    ASSERT_EQ(m.hierarchy.node_count(), built.hierarchy.node_count());
    ASSERT_EQ(but_identity_time(read_all(dir / "m.tch")), but_identity_time(bytes))
        << "byte " << i << ": not rewritten";
  }
}

// A cache file opened directly has no PLY to fall back on: every damaged
// version is an InputError naming the file, never a crash or a hierarchy.
TEST(Cache, OpeningADamagedCacheDirectlyIsAnInputError) {
  const fs::path dir = test::scratch_dir("cache_open_direct");
  save_cache(small(40), {1, 2, 3}, dir / "full.tch");
  const auto bytes = read_all(dir / "full.tch");
  for (std::size_t len = 0; len < bytes.size(); len += 7) {
    write_all(dir / "cut.tch", bytes, len);
    try {
      open_model(dir / "cut.tch");
      FAIL() << "length " << len << " opened";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("cut.tch"), std::string::npos) << e.what();
    }
  }
}

namespace {

// The child of the death test below: save_cache() under a file size limit,
// which kills the process with SIGXFSZ once the limit is reached.
[[noreturn]] void save_cache_under_size_limit(const Hierarchy& h, const CacheKey& key,
                                              const fs::path& cache, rlim_t limit) {
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  const rlimit size{limit, limit};
  setrlimit(RLIMIT_FSIZE, &size);
  save_cache(h, key, cache);
  std::_Exit(0);
}

}  // namespace

// A writer that dies mid-write (here: killed by the file size limit, SIGXFSZ,
// after part of the file went to disk) leaves the previous cache untouched and
// at most a partial temporary, which never loads and which open_model never
// reads.
TEST(CacheDeathTest, AWriterKilledMidWriteLeavesNoCacheThatLoads) {
  const fs::path dir = test::scratch_dir("cache_killed_writer");
  const Hierarchy before = small(300);
  const Hierarchy after = small(5000);
  save_cache(before, {1, 2, 3}, dir / "a.tch");
  const auto old_bytes = read_all(dir / "a.tch");
  constexpr rlim_t kLimit = 20000;  // bytes: a few arrays of the new file
  const CacheKey new_key{4, 5, 6};
  EXPECT_EXIT(save_cache_under_size_limit(after, new_key, dir / "a.tch", kLimit),
              testing::KilledBySignal(SIGXFSZ), "");

  EXPECT_EQ(read_all(dir / "a.tch"), old_bytes) << "the previous cache was touched";
  EXPECT_TRUE(load_cache(dir / "a.tch", CacheKey{1, 2, 3}, nullptr));
  std::string why;
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{4, 5, 6}, &why)) << "the new key";
  EXPECT_NE(why.find("stale"), std::string::npos) << why;
  std::vector<fs::path> temporaries;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename() != "a.tch") temporaries.push_back(e.path());
  ASSERT_EQ(temporaries.size(), 1u) << "the dead writer's temporary";
  EXPECT_EQ(temporaries[0].filename().string().rfind("a.tch.tmp-", 0), 0u) << temporaries[0];
  EXPECT_GT(fs::file_size(temporaries[0]), 0u);
  EXPECT_LE(fs::file_size(temporaries[0]), kLimit);
  EXPECT_FALSE(load_cache(temporaries[0], std::nullopt, &why));
  EXPECT_THROW(open_model(temporaries[0]), InputError);
}
