// SparseNodeArray: a value for every node id of a hierarchy, stored only in
// the blocks of ids where something was written (issue 45: the state of cuts
// and strategies follows the nodes they touch, not the hierarchy's size).
//
// Ids are cut into blocks of 2^kBits (1,024: one 4 KiB page of 32-bit
// values); a directory holds one pointer a block, and every block not yet
// written points at one block of the fill value, so a read is two loads and
// no branch. A cut of a few thousand nodes over a hierarchy of a billion
// holds a few blocks and a 16 MiB directory (16 bytes per 1,024 ids), where
// a plain array held 4 GB. Breadth-first ids put a node's children next to
// each other and a level's nodes in spatial order, so a cut fills the blocks
// it touches well (measured in tree_cut_test).
//
// Not thread-safe; copies are deep (a cut's copy for the Feedback Stage).
#pragma once

#include <algorithm>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace treecut {

template <class T>
class SparseNodeArray {
  static_assert(std::is_trivially_copyable_v<T>, "blocks are copied as bytes");

 public:
  static constexpr unsigned kBits = 10;
  static constexpr std::size_t kBlock = std::size_t{1} << kBits;

  SparseNodeArray() = default;
  /// SIZE ids, all holding FILL; nothing allocated but the directory.
  explicit SparseNodeArray(std::size_t size, T fill = T{}) { assign(size, fill); }

  SparseNodeArray(const SparseNodeArray& other) { *this = other; }
  SparseNodeArray& operator=(const SparseNodeArray& other) {
    if (this == &other) return *this;
    assign(other.size_, other.fill_value());
    for (std::size_t b = 0; b < other.blocks_.size(); ++b) {
      if (!other.blocks_[b]) continue;
      blocks_[b] = std::make_unique_for_overwrite<T[]>(kBlock);
      std::copy_n(other.blocks_[b].get(), kBlock, blocks_[b].get());
      dir_[b] = blocks_[b].get();
    }
    allocated_ = other.allocated_;
    return *this;
  }
  SparseNodeArray(SparseNodeArray&&) noexcept = default;
  SparseNodeArray& operator=(SparseNodeArray&&) noexcept = default;

  /// SIZE ids, all holding FILL: every block released.
  void assign(std::size_t size, T fill) {
    size_ = size;
    const std::size_t blocks = (size + kBlock - 1) / kBlock;
    fill_ = std::make_unique_for_overwrite<T[]>(kBlock);
    std::fill_n(fill_.get(), kBlock, fill);
    blocks_.clear();
    blocks_.resize(blocks);
    dir_.assign(blocks, fill_.get());
    allocated_ = 0;
  }

  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] T fill_value() const { return fill_ ? fill_[0] : T{}; }

  /// The value of id I (< size()).
  [[nodiscard]] T operator[](std::size_t i) const {
    assert(i < size_);
    return dir_[i >> kBits][i & (kBlock - 1)];
  }
  /// Sets id I (< size()) to V, allocating its block on the first write.
  void set(std::size_t i, T v) {
    assert(i < size_);
    T* block = dir_[i >> kBits];
    if (block == fill_.get()) {
      if (v == fill_[0]) return;  // keeps a block unwritten where it can
      block = allocate(i >> kBits);
    }
    block[i & (kBlock - 1)] = v;
  }
  /// A hint that id I will be read soon (its directory entry is in cache
  /// far more often than its value: 8 bytes cover 1,024 ids).
  void prefetch(std::size_t i) const { __builtin_prefetch(dir_[i >> kBits] + (i & (kBlock - 1))); }

  /// Releases the blocks that hold only the fill value again. O(blocks
  /// held); a caller runs it now and then, when most writes are behind it.
  void release_unused() {
    rewrite_held([](T v) { return v; });
  }
  /// Replaces every value V of the blocks held by FN(V), then releases the
  /// blocks left holding only the fill value (state that has aged out).
  /// O(blocks held).
  template <class Fn>
  void rewrite_held(Fn fn) {
    const T fill = fill_value();
    for (std::size_t b = 0; b < blocks_.size(); ++b) {
      T* block = blocks_[b].get();
      if (!block) continue;
      bool all_fill = true;
      for (std::size_t i = 0; i < kBlock; ++i) {
        block[i] = fn(block[i]);
        all_fill = all_fill && block[i] == fill;
      }
      if (all_fill) {
        blocks_[b].reset();
        dir_[b] = fill_.get();
        --allocated_;
      }
    }
  }
  /// Blocks written to (each kBlock values).
  [[nodiscard]] std::size_t blocks_held() const { return allocated_; }
  /// Bytes this array holds: its blocks, the fill block and the directory.
  [[nodiscard]] std::size_t memory_bytes() const {
    return (allocated_ + (fill_ ? 1 : 0)) * kBlock * sizeof(T) +
           dir_.size() * (sizeof(T*) + sizeof(std::unique_ptr<T[]>));
  }

 private:
  T* allocate(std::size_t b) {
    blocks_[b] = std::make_unique_for_overwrite<T[]>(kBlock);
    std::copy_n(fill_.get(), kBlock, blocks_[b].get());
    ++allocated_;
    return dir_[b] = blocks_[b].get();
  }

  std::size_t size_ = 0;
  std::unique_ptr<T[]> fill_;                 // kBlock copies of the fill value
  std::vector<T*> dir_;                       // a block's values, or fill_
  std::vector<std::unique_ptr<T[]>> blocks_;  // owners of the written blocks
  std::size_t allocated_ = 0;
};

}  // namespace treecut
