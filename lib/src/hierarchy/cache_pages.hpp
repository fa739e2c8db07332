// The pages of a hierarchy cache (issue 44, item 3): the nodes cut into
// subtrees of at most kPageNodes, each page quantized against its own box,
// stored as byte planes and compressed with zstd on its own, so a reader can
// verify and decode any page alone (what paged drawing will load). The
// anchors are Nexus and 3D Tiles (pages of a fixed size) and QSplat (the
// file is the hierarchy, quantized relative to the parent; here relative to
// the page).
//
// What a page keeps, and how exactly (the error bounds, tested in
// cache_test.cpp):
// - centers: 16 bits an axis on a grid of a power of two anchored at 0,
//   just fine enough for the page's box: the error is at most half a step,
//   a step under 2 * extent / 65534 of the page's box (or the float
//   precision of the coordinates, where that is coarser);
// - bounding radii: recomputed from the quantized centers and children
//   (the smallest sphere around the children's, as the builder makes
//   them), then rounded up on a logarithmic grid of 512 steps an octave
//   (at most +0.14 % a level; the levels below add up to under 0.3 %,
//   plus the centers' moves), so every sphere still contains its
//   children's;
// - the drawn radius of an interior node: 8 bits of its bounding radius;
//   a leaf's is its bounding radius;
// - priorities: 12 bits (monotone, as the refinement needs; a priority
//   weighs at most half a node's size, so 1/4095 moves no decision a
//   16-bit one would not, and 4 noisy bits a node less are half a byte a
//   point of a survey's cache);
// - normals (x and y, z as its difference from the unit vector's), cones,
//   colours and attributes: exact.
// Each value is stored as its difference from its parent's in the page
// (children lie near their parent, face its way and share its colour),
// which zstd then finds in the byte planes.
// The quantization is idempotent: a decoded hierarchy encodes to the same
// pages, so a cache rewritten from a loaded one changes nothing. Private
// to the library.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cache_layout.hpp"
#include "treecut/hierarchy.hpp"

namespace treecut::cache_pages {

/// Nodes a page holds at most (a subtree, or the top of one): 8,192, as
/// pages of about 5,000 nodes compress to 5 % less than 4,096's 1,300
/// (subtrees come in steps of four).
inline constexpr std::uint32_t kPageNodes = 8192;

/// A page's root as it decodes: what its parent's page makes its radii around.
struct Root {
  glm::vec3 center{0.0f};
  float radius = 0.0f;
};

/// A hierarchy's pages: the table (offsets from 0) and the compressed bytes.
struct Encoded {
  std::vector<cache_layout::PageRecord> table;
  std::vector<std::vector<unsigned char>> pages;
  Root root;                  ///< the hierarchy's root as page 0 decodes it
  std::vector<NodeId> roots;  ///< each page's root node
  /// Each page's nodes as runs of the encoded hierarchy's ids, and the
  /// points under its root (empty and 0 for encode_over's leaves).
  std::vector<std::vector<cache_layout::PageRun>> runs;
  std::vector<std::uint64_t> points;
};

/// Where the pages of a cache sit in the whole (cache_layout::PageLinksAt
/// has them on disk): what decode_page needs beside the page table.
struct PageLinks {
  std::vector<std::uint64_t> points;     ///< under each page's root
  std::vector<std::uint64_t> run_index;  ///< page p's runs: [run_index[p], run_index[p + 1])
  std::vector<cache_layout::PageRun> runs;
  std::vector<std::uint64_t> level_begin;  ///< the levels' first ids, and the node count
  [[nodiscard]] std::span<const cache_layout::PageRun> runs_of(std::size_t page) const {
    return std::span(runs).subspan(run_index[page], run_index[page + 1] - run_index[page]);
  }
};

/// The links of E, the pages of the whole of H (encode, encode_in_place).
PageLinks links_of(const Encoded& e, const Hierarchy& h);

/// Cuts H into pages, quantizes and compresses them (in parallel).
Encoded encode(const Hierarchy& h);

/// The pages of the levels over subtrees encoded on their own (the chunks
/// of the chunked build; subtree_roots.hpp): TOP's leaves stand for the
/// subtrees' roots, LEAF_ROOTS[i] the decoded sphere of leaf i (indexed by
/// node id). Each leaf is a page's root whose page is the subtree's first:
/// its record gets only where it hangs (parent page and node) and its
/// depth, its bytes are left empty, for the caller to put there. The
/// children of a node above a leaf are all pages' roots.
Encoded encode_over(const Hierarchy& top, std::span<const Root> leaf_roots);

/// encode(), and H's centers, radii, drawn radii and priorities rewritten
/// to the values its pages decode to: H becomes the hierarchy its cache
/// loads as, without decoding it. H's storage must be its own (no other
/// copy shares it: a build's, not a loaded cache's).
Encoded encode_in_place(const Hierarchy& h);

/// The nodes of a cache decoded from its pages.
struct Decoded {
  std::shared_ptr<const void> storage;  ///< owns every span below
  HierarchyArrays arrays;
  std::vector<NodeId> level_begin;
  /// The values of each attribute that is not constant, in record order.
  std::vector<std::span<const float>> attribute_values;
};

/// Where the pages are read from: R.bytes of them, at R.offset in the
/// file, returned in place or read into BUFFER. Called from any thread;
/// throws FileChangedError when the file no longer has them.
using PageSource = std::function<const unsigned char*(const cache_layout::PageRecord& r,
                                                      std::vector<unsigned char>& buffer)>;

/// A cache's page table and links, checked as a whole once (make): every
/// id held by exactly one page, each page's ids in increasing runs inside
/// its depths' levels, sibling pages one after the other. What decode_page
/// needs to decode any page alone. Immutable: any thread may use it.
class PageIndex {
 public:
  /// nullopt and *WHY ("page 3 of 12: bad node runs") when the table and
  /// the links do not hold together.
  static std::optional<PageIndex> make(std::vector<cache_layout::PageRecord> table, PageLinks links,
                                       std::uint64_t node_count, std::uint32_t level_count,
                                       std::uint32_t value_streams, std::string* why);

  [[nodiscard]] std::size_t pages() const { return table_.size(); }
  [[nodiscard]] const cache_layout::PageRecord& record(std::size_t p) const { return table_[p]; }
  [[nodiscard]] std::span<const cache_layout::PageRecord> table() const { return table_; }
  [[nodiscard]] const PageLinks& links() const { return links_; }
  [[nodiscard]] std::uint64_t node_count() const { return node_count_; }
  [[nodiscard]] std::uint32_t value_streams() const { return value_streams_; }
  /// The id of page P's root.
  [[nodiscard]] NodeId root_id(std::size_t p) const {
    return static_cast<NodeId>(links_.runs[links_.run_index[p]].first);
  }
  /// The id and depth of node LOCAL of page PAGE (its runs walked).
  [[nodiscard]] std::pair<NodeId, std::uint32_t> locate(std::uint32_t page,
                                                        std::uint32_t local) const;
  [[nodiscard]] std::uint32_t depth_of(std::uint32_t page, std::uint32_t local) const {
    return locate(page, local).second;
  }
  /// A page hanging from node LOCAL of another.
  struct Child {
    std::uint32_t local, page;
  };
  /// The pages hanging from page P's nodes, by node, then page.
  [[nodiscard]] std::span<const Child> child_pages(std::uint32_t p) const;

 private:
  PageIndex() = default;
  std::vector<cache_layout::PageRecord> table_;
  PageLinks links_;
  std::uint64_t node_count_ = 0;
  std::uint32_t value_streams_ = 0;
  std::vector<Child> children_;             // by parent page, node, page
  std::vector<std::uint64_t> group_begin_;  // page p's: [group_begin_[p], group_begin_[p + 1])
};

/// Where a decoded page's nodes go: arrays of the whole, indexed by id,
/// and one for each attribute that is not constant.
struct NodeSink {
  glm::vec4* center_radius;
  float* splat_radius;
  glm::i16vec4* normal_cone;
  glm::u8vec4* color;
  float* priority;
  std::uint32_t* point_count;
  NodeId* parent;
  NodeId* first_child;
  std::uint8_t* child_count;
  std::uint8_t* depth;
  std::vector<float*> values;
};

/// Reads, verifies and decodes page P of INDEX through SOURCE, writing its
/// nodes (links, point counts, values) into OUT at their ids and nothing
/// else (RAW: scratch). Empty, or what is wrong with the page ("checksum
/// mismatch (corrupted)"), without its name; never trusts a byte.
std::string decode_page(const PageIndex& index, std::uint32_t p, const PageSource& source,
                        const NodeSink& out, std::vector<unsigned char>& raw);

/// Every page of INDEX, in parallel, into arrays of its own. A page whose
/// checksum, size, counts or links do not hold is named in *WHY ("page 3
/// of 12: checksum mismatch (corrupted)") and nothing is returned.
std::optional<Decoded> decode(const PageIndex& index, const PageSource& source, std::string* why);

}  // namespace treecut::cache_pages
