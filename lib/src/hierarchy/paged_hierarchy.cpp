// Paged drawing's hierarchy (paged_hierarchy.hpp has the promises): arrays
// of reserved address space, groups of sibling pages read by I/O threads in
// the order asked, published and given back by the thread that iterates.
//
// The unit is a group: the pages hanging from one node (all of a node's
// children are pages' roots when one is, cache_pages.hpp), read, published
// and given back together, since the node's child count shows them all or
// none. A group is known once the page of its node is resident; page 0 is
// always resident.
#include "treecut/paged_hierarchy.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <utility>

#include "cache_format.hpp"
#include "cache_pages.hpp"
#include "http_source.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/reserved_array.hpp"

namespace treecut {

using cache_layout::PageRecord;
using cache_layout::PageRun;
using ListHolds = PagedHierarchy::ListHolds;

namespace {

template <class T>
using Reserved = ReservedArray<T>;

// The arrays of the whole, each reserved, their memory pages counted: the
// levels of a page are runs of ids that share memory pages with other
// pages' runs, and a memory page goes back when no value on it is in use.
struct Arrays {
  static constexpr PageSharing kShared = PageSharing::counted;
  explicit Arrays(std::size_t n, std::size_t streams)
      : center_radius(n, kShared),
        splat_radius(n, kShared),
        normal_cone(n, kShared),
        color(n, kShared),
        priority(n, kShared),
        point_count(n, kShared),
        parent(n, kShared),
        first_child(n, kShared),
        child_count(n, kShared),
        depth(n, kShared) {
    for (std::size_t s = 0; s < streams; ++s)
      values.push_back(std::make_unique<Reserved<float>>(n, kShared));
  }
  Reserved<glm::vec4> center_radius;
  Reserved<float> splat_radius;
  Reserved<glm::i16vec4> normal_cone;
  Reserved<glm::u8vec4> color;
  Reserved<float> priority;
  Reserved<std::uint32_t> point_count;
  Reserved<NodeId> parent, first_child;
  Reserved<std::uint8_t> child_count, depth;
  std::vector<std::unique_ptr<Reserved<float>>> values;

  [[nodiscard]] cache_pages::NodeSink sink() const {
    cache_pages::NodeSink s{center_radius.data(),
                            splat_radius.data(),
                            normal_cone.data(),
                            color.data(),
                            priority.data(),
                            point_count.data(),
                            parent.data(),
                            first_child.data(),
                            child_count.data(),
                            depth.data(),
                            {}};
    for (const auto& v : values) s.values.push_back(v->data());
    return s;
  }
  template <class Fn>
  void each(Fn&& fn) const {
    fn(center_radius), fn(splat_radius), fn(normal_cone), fn(color), fn(priority);
    fn(point_count), fn(parent), fn(first_child), fn(child_count), fn(depth);
    for (const auto& v : values) fn(*v);
  }
  // Before values [FIRST, FIRST + COUNT) are written (ReservedArray::use).
  void use(std::uint64_t first, std::uint64_t count) const {
    each([&](const auto& a) { a.use(first, count); });
  }
  void release(std::uint64_t first, std::uint64_t count) const {
    each([&](const auto& a) { a.release(first, count); });
  }
  // The bytes of the memory pages the system holds under the first N values of each.
  [[nodiscard]] std::uint64_t held_bytes(std::uint64_t n) const {
    std::uint64_t bytes = 0;
    each([&](const auto& a) { bytes += a.held_bytes(n); });
    return bytes;
  }
};

enum class State : std::uint8_t { hidden, in_flight, loaded, resident, failed };

// The pages hanging from one node.
struct Group {
  NodeId owner = kNoNode;  // the node whose group holds this node's page (kNoNode: page 0)
  std::uint32_t first_page = 0, pages = 0;
  State state = State::hidden;
  std::uint32_t busy_below = 0;  // groups of its pages' nodes not hidden
  std::uint64_t nodes = 0, file_bytes = 0;
  std::uint64_t last_used = 0;
};

}  // namespace

struct PagedHierarchy::Impl {
  std::filesystem::path path;
  PagingOptions options;
  std::unique_ptr<detail::ByteSource> source;  // the file, or the URL
  std::optional<detail::CacheOutline> outline;
  std::shared_ptr<Arrays> arrays;
  Hierarchy hierarchy;
  std::uint64_t node_bytes = 0;

  mutable std::mutex mutex;      // everything below
  std::condition_variable wake;  // the I/O threads: a request, room, or the end
  std::condition_variable idle;  // wait_idle(): a group read
  bool stop = false;
  std::unordered_map<NodeId, Group> groups;
  std::vector<NodeId> requests;  // hidden groups, most wanted first
  std::vector<NodeId> loaded;    // read, to publish
  std::uint64_t resident_bytes = 0, pending_bytes = 0, resident_nodes = 0, resident_pages = 0;
  std::uint64_t in_flight = 0, loaded_count = 0, evicted = 0, failed = 0, bytes_read = 0;
  std::uint64_t now = 0;      // evict() calls
  bool memory_short = false;  // at the last evict()
  std::vector<std::string> problems;
  // Immutable after open(): every run by first id (place_of): its page,
  // and where the run ends in the page's order of nodes.
  struct RunStart {
    std::uint64_t first;
    std::uint32_t page, end;
  };
  std::vector<RunStart> run_starts;
  std::uint64_t least_bytes = 0, full_detail_bytes = 0;
  std::vector<std::thread> threads;

  ~Impl() {
    {
      std::lock_guard lock(mutex);
      stop = true;
    }
    wake.notify_all();
    for (std::thread& t : threads) t.join();
  }

  [[nodiscard]] const cache_pages::PageIndex& index() const { return outline->index; }

  // Reads page R's bytes at their place in the file.
  const unsigned char* read(const PageRecord& r, std::vector<unsigned char>& buffer) {
    buffer.resize(r.bytes);
    source->read(r.offset, buffer.data(), r.bytes);
    return buffer.data();
  }

  // Decodes page P into the arrays, its nodes with child pages left
  // without children (nobody may reach them before publish()). Empty, or
  // what is wrong.
  std::string load_page(std::uint32_t p, std::vector<unsigned char>& raw) {
    std::string problem;
    try {
      problem = cache_pages::decode_page(
          index(), p,
          [this](const PageRecord& r, std::vector<unsigned char>& b) { return read(r, b); },
          arrays->sink(), raw);
    } catch (const std::exception& e) {  // "CACHE: reason": the line names CACHE once
      const std::string text = e.what(), prefix = quoted_name(path) + ": ";
      problem = text.rfind(prefix, 0) == 0 ? text.substr(prefix.size()) : text;
    }
    if (!problem.empty()) return problem;
    for (const cache_pages::PageIndex::Child& c : index().child_pages(p))
      arrays->child_count.data()[index().locate(p, c.local).first] = 0;
    return {};
  }

  // The groups hanging from the nodes of the pages of OWNER's group (from
  // page 0's for kNoNode), now that they are resident.
  void add_groups(NodeId owner, std::uint32_t first_page, std::uint32_t pages) {
    for (std::uint32_t p = first_page; p < first_page + pages; ++p) {
      const std::span<const cache_pages::PageIndex::Child> children = index().child_pages(p);
      for (std::size_t g = 0; g < children.size();) {
        std::size_t k = g;
        Group group;
        group.owner = owner;
        group.first_page = children[g].page;
        for (; k < children.size() && children[k].local == children[g].local; ++k) {
          const PageRecord& r = index().record(children[k].page);
          ++group.pages, group.nodes += r.node_count, group.file_bytes += r.bytes;
        }
        groups[index().locate(p, children[g].local).first] = group;
        g = k;
      }
    }
  }

  void forget_groups(std::uint32_t first_page, std::uint32_t pages) {
    for (std::uint32_t p = first_page; p < first_page + pages; ++p)
      for (const cache_pages::PageIndex::Child& c : index().child_pages(p))
        groups.erase(index().locate(p, c.local).first);
  }

  [[nodiscard]] bool fits(const Group& g) const {
    return options.memory_bytes == 0 ||
           resident_bytes + pending_bytes + g.nodes * node_bytes <= options.memory_bytes;
  }

  // The I/O threads: the most wanted hidden group, when it fits.
  void serve() {
    std::vector<unsigned char> raw;
    std::unique_lock lock(mutex);
    while (!stop) {
      auto wanted = groups.end();
      std::size_t at = 0;
      for (; at < requests.size(); ++at) {
        wanted = groups.find(requests[at]);
        if (wanted != groups.end() && wanted->second.state == State::hidden) break;
        wanted = groups.end();
      }
      if (wanted == groups.end() || !fits(wanted->second)) {
        wake.wait(lock);
        continue;
      }
      const NodeId node = wanted->first;
      Group& g = wanted->second;
      requests.erase(requests.begin() + static_cast<std::ptrdiff_t>(at));
      g.state = State::in_flight;
      // Counted before the read writes them (a release of a page beside
      // them then keeps the memory pages they share).
      for (std::uint32_t q = g.first_page; q < g.first_page + g.pages; ++q) use_page(q);
      pending_bytes += g.nodes * node_bytes;
      ++in_flight;
      if (g.owner != kNoNode) ++groups.at(g.owner).busy_below;
      const std::uint32_t first = g.first_page, pages = g.pages;
      lock.unlock();
      std::string problem;
      std::uint32_t p = first;
      for (; p < first + pages && problem.empty(); ++p) problem = load_page(p, raw);
      lock.lock();
      // The group is still there: its owner's page is not given back while
      // a group below it is busy.
      Group& done = groups.at(node);
      if (problem.empty()) {
        done.state = State::loaded;
        loaded.push_back(node);
      } else {
        for (std::uint32_t q = first; q < first + pages; ++q) release_page(q);
        done.state = State::failed;
        pending_bytes -= done.nodes * node_bytes;
        --in_flight, ++failed;
        if (done.owner != kNoNode) --groups.at(done.owner).busy_below;
        problems.push_back(quoted_name(path) + ": page " + std::to_string(p - 1) + " of " +
                           std::to_string(index().pages()) + ": " + problem);
      }
      bytes_read += done.file_bytes;
      idle.notify_all();
    }
  }

  void index_runs() {
    const cache_pages::PageLinks& links = index().links();
    for (std::uint32_t p = 0; p < index().pages(); ++p) {
      std::uint32_t k = 0;
      for (const PageRun& run : links.runs_of(p))
        run_starts.push_back({run.first, p, k += run.count});
    }
    std::sort(run_starts.begin(), run_starts.end(),
              [](const RunStart& a, const RunStart& b) { return a.first < b.first; });
  }

  // The groups hanging from page P's nodes, each as its pages [first, end).
  template <class Fn>
  void for_each_group_below(std::uint32_t p, Fn&& fn) const {
    const std::span<const cache_pages::PageIndex::Child> children = index().child_pages(p);
    for (std::size_t g = 0; g < children.size();) {
      std::size_t k = g;
      while (k < children.size() && children[k].local == children[g].local) ++k;
      fn(children[g].page, children[g].page + static_cast<std::uint32_t>(k - g));
      g = k;
    }
  }

  // least_bytes: page 0 and the largest group; full_detail_bytes: the
  // heaviest chain of groups from the root (below[p]: the heaviest chain
  // hanging from page p's nodes), pages visited children first.
  void measure_budgets() {
    const std::uint32_t n = static_cast<std::uint32_t>(index().pages());
    std::vector<std::uint64_t> below(n, 0);
    std::vector<std::uint8_t> done(n, 0);
    std::vector<std::uint32_t> stack{0};
    std::uint64_t largest = 0;
    while (!stack.empty()) {
      const std::uint32_t p = stack.back();
      bool ready = true;
      if (!done[p])
        for_each_group_below(p, [&](std::uint32_t first, std::uint32_t end) {
          for (std::uint32_t q = first; q < end; ++q)
            if (!done[q]) stack.push_back(q), ready = false;
        });
      if (!ready) continue;
      stack.pop_back();
      if (done[p]) continue;
      done[p] = 1;
      for_each_group_below(p, [&](std::uint32_t first, std::uint32_t end) {
        std::uint64_t nodes = 0, deepest = 0;
        for (std::uint32_t q = first; q < end; ++q)
          nodes += index().record(q).node_count, deepest = std::max(deepest, below[q]);
        largest = std::max(largest, nodes);
        below[p] = std::max(below[p], nodes + deepest);
      });
    }
    const std::uint64_t root = index().record(0).node_count;
    least_bytes = (root + largest) * node_bytes;
    full_detail_bytes = (root + below[0]) * node_bytes;
  }

  // Page P's runs of ids in the arrays: about to be written (use), or
  // given back (release).
  void use_page(std::uint32_t p) const {
    for (const PageRun& run : index().links().runs_of(p)) arrays->use(run.first, run.count);
  }
  void release_page(std::uint32_t p) const {
    for (const PageRun& run : index().links().runs_of(p)) arrays->release(run.first, run.count);
  }

  // Whether every list holds node N or an ancestor of it: then no list
  // holds a node below N. (One list above N is not enough: another, an
  // older cut still drawn, may reach below it.)
  [[nodiscard]] bool above(NodeId n, std::span<const ListHolds> lists) const {
    const HierarchyArrays& a = hierarchy.arrays();
    for (const ListHolds& holds : lists) {
      NodeId up = n;
      while (up != kNoNode && !holds(up)) up = a.parent[up];
      if (up == kNoNode) return false;
    }
    return true;
  }

  void give_back(NodeId node, Group& g) {
    arrays->child_count.data()[node] = 0;
    forget_groups(g.first_page, g.pages);
    for (std::uint32_t p = g.first_page; p < g.first_page + g.pages; ++p) release_page(p);
    g.state = State::hidden;
    resident_bytes -= g.nodes * node_bytes;
    resident_nodes -= g.nodes, resident_pages -= g.pages;
    if (g.owner != kNoNode) --groups.at(g.owner).busy_below;
    ++evicted;
  }
};

bool is_cache_url(std::string_view where) {
  return detail::is_http_url(where);
}

PagedHierarchy::PagedHierarchy(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PagedHierarchy::~PagedHierarchy() = default;

std::unique_ptr<PagedHierarchy> PagedHierarchy::open(const std::filesystem::path& cache,
                                                     const PagingOptions& options) {
  auto impl = std::make_unique<Impl>();
  Impl& m = *impl;
  m.path = cache;
  m.options = options;
  if (detail::is_http_url(cache.native())) {
    detail::HttpOptions http;
    http.stall_ms = options.stall_ms;
    m.source = std::make_unique<detail::HttpSource>(cache.native(), http);
  } else {
    m.source = std::make_unique<detail::FileSource>(cache);
  }
  std::string why;
  try {
    m.outline = detail::read_cache_outline(*m.source, &why);
  } catch (const FileChangedError& e) {  // (the source's lines name the file)
    throw InputError(e.what());
  }
  if (!m.outline) throw InputError(quoted_name(cache) + ": " + why);
  const cache_pages::PageIndex& index = m.index();
  const auto n = static_cast<std::size_t>(index.node_count());
  const std::uint32_t streams = index.value_streams();
  m.arrays = std::make_shared<Arrays>(n, streams);
  m.node_bytes = sizeof(glm::vec4) + sizeof(float) + sizeof(glm::i16vec4) + sizeof(glm::u8vec4) +
                 sizeof(float) + sizeof(std::uint32_t) + 2 * sizeof(NodeId) + 2 + 4 * streams;
  std::vector<unsigned char> raw;
  m.use_page(0);
  if (std::string problem = m.load_page(0, raw); !problem.empty())
    throw InputError(quoted_name(cache) + ": page 0 of " + std::to_string(index.pages()) + ": " +
                     problem);
  const PageRecord& root = index.record(0);
  m.resident_bytes = root.node_count * m.node_bytes;
  m.resident_nodes = root.node_count, m.resident_pages = 1, m.bytes_read = root.bytes;
  m.add_groups(kNoNode, 0, 1);
  m.index_runs();
  m.measure_budgets();
  if (options.memory_bytes != 0 && options.memory_bytes < m.least_bytes)
    throw InputError(quoted_name(cache) + ": a memory budget of " + mib_text(options.memory_bytes) +
                     " is below the " + mib_text(m.least_bytes) +
                     " its first page and its largest group of pages take together (the "
                     "finest detail at one place needs " +
                     mib_text(m.full_detail_bytes) + ")");
  if (options.node_limit != 0) {
    const std::uint64_t held = std::max(options.node_limit * m.node_bytes, m.least_bytes);
    if (options.memory_bytes == 0 || held < options.memory_bytes) m.options.memory_bytes = held;
  }

  const Arrays& a = *m.arrays;
  HierarchyArrays spans{a.center_radius.span(n), a.splat_radius.span(n), a.normal_cone.span(n),
                        a.color.span(n),         a.priority.span(n),     a.point_count.span(n),
                        a.parent.span(n),        a.first_child.span(n),  a.child_count.span(n),
                        a.depth.span(n)};
  std::vector<NodeAttribute> attributes = m.outline->attributes;
  for (std::size_t k = 0, s = 0; k < attributes.size(); ++k)
    if (m.outline->varying[k]) attributes[k].values = a.values[s++]->span(n);
  const std::vector<std::uint64_t>& lb = index.links().level_begin;
  m.hierarchy = Hierarchy::from_arrays(m.arrays, spans, std::vector<NodeId>(lb.begin(), lb.end()),
                                       m.outline->bounds_min, m.outline->bounds_max,
                                       m.outline->frame, std::move(attributes))
                    .with_notes(m.outline->notes);
  for (unsigned t = 0; t < std::max(1u, options.io_threads); ++t)
    m.threads.emplace_back([&m] {
      // Pages are decoded with the cycles the render thread leaves (nice
      // +10, as the stage's Low priority: never starved, as SCHED_IDLE
      // would be under a busy renderer). On 2 cores, decoding at the
      // render thread's priority took its frames' time.
      (void)::setpriority(PRIO_PROCESS, 0, std::min(::getpriority(PRIO_PROCESS, 0) + 10, 19));
      m.serve();
    });
  return std::unique_ptr<PagedHierarchy>(new PagedHierarchy(std::move(impl)));
}

const Hierarchy& PagedHierarchy::hierarchy() const {
  return impl_->hierarchy;
}

bool PagedHierarchy::hidden(NodeId n) const {
  return impl_->hierarchy.is_hidden(n);
}

std::vector<NodeId> PagedHierarchy::rank(std::span<const NodeId> wanted, const ViewSnapshot& view,
                                         std::size_t at_most) const {
  const Hierarchy& h = impl_->hierarchy;
  std::vector<std::pair<float, NodeId>> ranked;
  for (const NodeId n : wanted)
    if (h.is_hidden(n)) ranked.emplace_back(-view.projected_radius_px(h.center(n), h.radius(n)), n);
  const std::size_t k = std::min(at_most, ranked.size());
  std::partial_sort(ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(k), ranked.end());
  std::vector<NodeId> out;
  for (std::size_t i = 0; i < k; ++i) out.push_back(ranked[i].second);
  return out;
}

void PagedHierarchy::request(std::span<const NodeId> nodes) {
  Impl& m = *impl_;
  {
    std::lock_guard lock(m.mutex);
    m.requests.clear();
    for (const NodeId n : nodes)
      if (const auto it = m.groups.find(n);
          it != m.groups.end() && it->second.state == State::hidden)
        m.requests.push_back(n);
  }
  m.wake.notify_all();
}

std::size_t PagedHierarchy::publish(std::vector<NodeId>* revealed) {
  Impl& m = *impl_;
  std::lock_guard lock(m.mutex);
  if (revealed) revealed->insert(revealed->end(), m.loaded.begin(), m.loaded.end());
  for (const NodeId node : m.loaded) {
    Group& g = m.groups.at(node);
    g.state = State::resident;
    g.last_used = m.now;
    m.add_groups(node, g.first_page, g.pages);
    // Its pages' nodes were written by the I/O thread before it took the
    // lock; the node's children appear now, on the thread that iterates.
    m.arrays->child_count.data()[node] = static_cast<std::uint8_t>(g.pages);
    m.pending_bytes -= g.nodes * m.node_bytes;
    m.resident_bytes += g.nodes * m.node_bytes;
    m.resident_nodes += g.nodes, m.resident_pages += g.pages;
    --m.in_flight, ++m.loaded_count;
  }
  const std::size_t published = m.loaded.size();
  m.loaded.clear();
  return published;
}

std::size_t PagedHierarchy::evict(std::span<const ListHolds> lists,
                                  std::vector<NodeId>* concealed) {
  Impl& m = *impl_;
  std::unique_lock lock(m.mutex);
  ++m.now;
  std::vector<std::pair<std::uint64_t, NodeId>> candidates;  // (last used, node)
  for (auto& [node, g] : m.groups) {
    if (g.state != State::resident) continue;
    if (!m.above(node, lists))
      g.last_used = m.now;
    else if (g.busy_below == 0)
      candidates.emplace_back(g.last_used, node);
  }
  m.memory_short = false;
  if (m.options.memory_bytes == 0) return 0;
  // What is asked next, and what it needs.
  std::uint64_t need = 0;
  for (const NodeId n : m.requests)
    if (const auto it = m.groups.find(n);
        it != m.groups.end() && it->second.state == State::hidden) {
      need = it->second.nodes * m.node_bytes;
      break;
    }
  std::sort(candidates.begin(), candidates.end());
  std::size_t given = 0;
  for (const auto& [used, node] : candidates) {
    if (m.resident_bytes + m.pending_bytes + need <= m.options.memory_bytes) break;
    Group& g = m.groups.at(node);
    if (g.busy_below != 0) continue;  // (a group given back just now was below it)
    m.give_back(node, g);
    if (concealed) concealed->push_back(node);
    ++given;
  }
  m.memory_short = need > 0 && m.resident_bytes + m.pending_bytes + need > m.options.memory_bytes;
  lock.unlock();
  if (given) m.wake.notify_all();
  return given;
}

bool PagedHierarchy::wait_idle(int timeout_ms) {
  Impl& m = *impl_;
  std::unique_lock lock(m.mutex);
  return m.idle.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] {
    if (m.in_flight > m.loaded.size()) return false;  // a group is being read
    for (const NodeId n : m.requests) {
      const auto it = m.groups.find(n);
      if (it != m.groups.end() && it->second.state == State::hidden && m.fits(it->second))
        return false;
    }
    return true;
  });
}

std::uint32_t PagedHierarchy::pages() const {
  return static_cast<std::uint32_t>(impl_->index().pages());
}

NodePlace PagedHierarchy::place_of(NodeId n) const {
  const auto& starts = impl_->run_starts;
  // The last run starting at or before N: the runs tile the ids (PageIndex).
  const auto it = std::upper_bound(starts.begin(), starts.end(), std::uint64_t{n},
                                   [](std::uint64_t id, const auto& s) { return id < s.first; });
  if (it == starts.begin()) return {};
  return {std::prev(it)->page, std::prev(it)->end};
}

void PagedHierarchy::page_ranges(std::uint32_t p, std::vector<NodeRange>& out) const {
  out.clear();
  for (const PageRun& run : impl_->index().links().runs_of(p))
    out.push_back({static_cast<NodeId>(run.first), run.count});
}

std::uint32_t PagedHierarchy::page_nodes(std::uint32_t p) const {
  return impl_->index().record(p).node_count;
}

std::uint64_t PagedHierarchy::memory_budget() const {
  return impl_->options.memory_bytes;
}

std::uint64_t PagedHierarchy::full_detail_memory() const {
  return impl_->full_detail_bytes;
}

PagingStats PagedHierarchy::stats() const {
  const Impl& m = *impl_;
  std::lock_guard lock(m.mutex);
  PagingStats s;
  s.pages = m.index().pages();
  s.resident_pages = m.resident_pages, s.resident_nodes = m.resident_nodes;
  s.resident_bytes = m.resident_bytes;
  for (const NodeId n : m.requests)
    if (const auto it = m.groups.find(n); it != m.groups.end() && it->second.state == State::hidden)
      s.requested += it->second.pages;
  s.in_flight = m.in_flight;
  s.loaded = m.loaded_count, s.evicted = m.evicted, s.failed = m.failed;
  s.bytes_read = m.bytes_read;
  s.memory_short = m.memory_short;
  return s;
}

std::vector<std::string> PagedHierarchy::take_problems() {
  std::lock_guard lock(impl_->mutex);
  return std::exchange(impl_->problems, {});
}

std::uint64_t PagedHierarchy::bytes_per_node() const {
  return impl_->node_bytes;
}

std::uint64_t PagedHierarchy::held_bytes() const {
  return impl_->arrays->held_bytes(impl_->hierarchy.node_count());
}

}  // namespace treecut
