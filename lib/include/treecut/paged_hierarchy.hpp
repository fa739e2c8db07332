// A hierarchy drawn from its cache's pages (issue 45, item 1): only the
// pages that are wanted are read, within a memory budget, by I/O threads
// in the order they are asked for, and the least recently used are given
// back. QSplat draws its file while it streams in (Rusinkiewicz & Levoy
// 2000, section 4.2); Potree's viewer loads nodes by priority within a
// point budget and keeps an LRU of them.
//
// The hierarchy is one Hierarchy (the same type, ids and arrays a whole
// load gives), its arrays reserved address space the size of the whole
// that only resident pages occupy: a node of a page that is not resident
// reads as zeros, and a node whose children are in pages not yet resident
// (or given back) has no children. So a cut of this hierarchy only holds
// resident nodes, every strategy works on it unchanged, and a node whose
// children are on their way stays a leaf of the cut until they arrive
// (its point count is still its subtree's: hidden(n)). A model whose pages
// are all resident is the hierarchy a whole load gives, id for id.
//
// Threads. request(), publish(), evict() and stats() are called by one
// thread, the one that iterates the strategies, between iterations: the
// children a node gains or loses then change under nobody. The I/O threads
// write only the nodes of pages nobody can reach yet (their parent has no
// children until publish()), and give them back only after evict() hid
// them. Whoever reads a node outside that thread (a renderer drawing a
// list, or copying a list's pages to the GPU) must hold it, or a node below
// it, in a list evict() was told of: its page is resident while it does.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/hierarchy.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut {

/// Where a node lies in a cache's pages (PagedHierarchy::place_of).
struct NodePlace {
  std::uint32_t page = 0;
  std::uint32_t prefix = 0;  ///< the page's nodes up to the end of the node's run
};

struct PagingOptions {
  /// The resident pages' node arrays at most, in bytes (0: no limit). The
  /// first page is always resident, whatever its size.
  std::uint64_t memory_bytes = 0;
  /// The resident nodes at most (0: no limit): what the GPU pool that
  /// draws them holds, so that the memory holds no page the GPU could not
  /// draw (its nodes would be drawn as their ancestors while the strategy
  /// takes them as shown). The budget is the lesser of memory_bytes and
  /// these nodes' bytes, never below what page 0 and the largest group of
  /// sibling pages take.
  std::uint64_t node_limit = 0;
  /// Threads reading pages (each reads a group of sibling pages at a time).
  unsigned io_threads = 1;
  /// A cache by URL: a read that receives nothing for this long fails
  /// (the page's line says so; its parent stays a leaf).
  int stall_ms = 15000;
};

/// What the pages are doing; counts of pages unless said otherwise.
struct PagingStats {
  std::uint64_t pages = 0;  ///< in the file
  std::uint64_t resident_pages = 0, resident_nodes = 0;
  std::uint64_t resident_bytes = 0;  ///< their node arrays (what the budget bounds)
  std::uint64_t requested = 0;       ///< asked for, not yet being read
  std::uint64_t in_flight = 0;       ///< being read, or read and not yet published
  std::uint64_t loaded = 0, evicted = 0, failed = 0;  ///< since opening
  std::uint64_t bytes_read = 0;                       ///< of the file, since opening
  /// At the last evict(): what is asked next did not fit the budget even
  /// after every page no list reaches into was given back. The lists hold
  /// the memory: IterationInput::memory_short asks the strategy to let go
  /// of what the view does not need.
  bool memory_short = false;
};

/// Whether WHERE is a URL PagedHierarchy::open reads (http:// or https://).
bool is_cache_url(std::string_view where);

class PagedHierarchy {
 public:
  /// Opens CACHE, a file or an http:// or https:// URL (read by HTTP range
  /// requests: item 2 of issue 45): its meta part read and verified, its
  /// first page read.
  /// Throws InputError "CACHE: REASON" when it is no cache of this format,
  /// its meta part or its first page do not check out, or the budget is
  /// below what page 0 and the largest group of sibling pages take
  /// together (a group that could never be read).
  static std::unique_ptr<PagedHierarchy> open(const std::filesystem::path& cache,
                                              const PagingOptions& options = {});
  ~PagedHierarchy();
  PagedHierarchy(const PagedHierarchy&) = delete;
  PagedHierarchy& operator=(const PagedHierarchy&) = delete;

  /// The hierarchy as far as it is resident (see the top of this file).
  /// Valid as long as this object; copies share its arrays.
  [[nodiscard]] const Hierarchy& hierarchy() const;

  /// Whether node N of a resident page is a leaf only because its
  /// children are not resident (it holds more than one point).
  [[nodiscard]] bool hidden(NodeId n) const;

  /// The hidden nodes of WANTED (what an iteration reported,
  /// IterationOutput::wanted), the largest on screen under VIEW first (their
  /// projected radius), at most AT_MOST: the order to request() them in.
  [[nodiscard]] std::vector<NodeId> rank(std::span<const NodeId> wanted, const ViewSnapshot& view,
                                         std::size_t at_most = 64) const;

  /// Asks for the children of NODES (hidden ones; others are ignored),
  /// the most wanted first; replaces what was asked before. The I/O
  /// threads read the first that fits the budget, in this order.
  void request(std::span<const NodeId> nodes);

  /// Makes the pages read since the last call part of the hierarchy (their
  /// parents get their children, appended to REVEALED: what the next
  /// iteration's IterationInput::revealed says). Returns how many groups
  /// of sibling pages.
  std::size_t publish(std::vector<NodeId>* revealed = nullptr);

  /// Whether a list anyone reads (a cut, a list being drawn) holds node n.
  using ListHolds = std::function<bool(NodeId)>;

  /// Gives back pages until what is asked next fits the budget: the least
  /// recently used that no list reaches into (LISTS, one predicate a list:
  /// a page's nodes are in no list when every list holds the node its
  /// group hangs from or an ancestor of it), deepest first (a page only
  /// when none below it is resident). Also marks the pages the lists use
  /// as used now. The nodes that lost their children are appended to
  /// CONCEALED (IterationInput::concealed). Returns how many groups were
  /// given back. Sets PagingStats::memory_short.
  std::size_t evict(std::span<const ListHolds> lists, std::vector<NodeId>* concealed = nullptr);

  /// Waits until nothing asked for is waiting or being read (what a test
  /// or an offline render may do; a frame never does). False after
  /// TIMEOUT_MS.
  bool wait_idle(int timeout_ms);

  /// Pages in the file; node ids live in exactly one each.
  [[nodiscard]] std::uint32_t pages() const;
  /// The page holding node N (any node of the file, resident or not) and
  /// how many of its nodes, in the page's order, reach N's level: the end
  /// of N's run (a page's runs go level by level). A binary search of the
  /// pages' runs; any thread.
  [[nodiscard]] NodePlace place_of(NodeId n) const;
  [[nodiscard]] std::uint32_t page_of(NodeId n) const { return place_of(n).page; }
  /// Page P's nodes as runs of ids, in the page's order (replaces OUT's
  /// content). Any thread.
  void page_ranges(std::uint32_t p, std::vector<NodeRange>& out) const;
  [[nodiscard]] std::uint32_t page_nodes(std::uint32_t p) const;
  /// The memory budget: PagingOptions::memory_bytes, or what its
  /// node_limit's nodes take when that is less.
  [[nodiscard]] std::uint64_t memory_budget() const;
  /// Bytes of the budget that the heaviest chain of groups from the root
  /// takes: what the finest detail at any one place needs (a view of more
  /// places needs more).
  [[nodiscard]] std::uint64_t full_detail_memory() const;

  [[nodiscard]] PagingStats stats() const;
  /// Pages that could not be read since the last call, a line each:
  /// "CACHE: page 3 of 12: checksum mismatch (corrupted)". Their parent
  /// stays a leaf; the rest is drawn.
  std::vector<std::string> take_problems();

  /// Bytes a resident node takes in the arrays (the budget's unit).
  [[nodiscard]] std::uint64_t bytes_per_node() const;
  /// The bytes of the memory pages the system holds under the node arrays
  /// (mincore): the resident nodes' bytes, and the rest of the memory pages
  /// at the ends of their runs (a page's levels are runs of ids; each end
  /// shares a memory page with another page's run, held or not). What RSS
  /// counts of them. O(the arrays' memory pages): for a report, not a frame.
  [[nodiscard]] std::uint64_t held_bytes() const;

 private:
  struct Impl;
  explicit PagedHierarchy(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace treecut
