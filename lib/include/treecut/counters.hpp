// Named counters: what a strategy iteration measures beyond the fixed
// IterationResult fields, published by name so that the HUD, `treecut
// render`'s stats.csv and summary.json and the benchmarks show them without
// knowing the strategy (a plugin's too). The hoq strategy publishes its block
// counts (docs/occlusion.md), the budget strategy its culling counts and
// phase times (docs/many-objects.md).
//
// Fixed capacity and trivially copyable: the counters travel inside
// IterationResult from the stage thread's outbox to the render thread's
// StageCounters::last in poll(), which must not allocate.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string_view>

namespace treecut {

/// One counter of an iteration.
struct Counter {
  static constexpr std::size_t kMaxName = 31;  ///< characters of a name
  static constexpr std::size_t kMaxUnit = 11;  ///< characters of a unit

  std::array<char, kMaxName + 1> name_storage{};
  std::array<char, kMaxUnit + 1> unit_storage{};
  double value = 0.0;

  /// lower_snake_case, unique in its iteration; a stats.csv column.
  [[nodiscard]] std::string_view name() const { return name_storage.data(); }
  /// What one of it is: "blocks", "objects", "ms", ... ("" for a ratio).
  [[nodiscard]] std::string_view unit() const { return unit_storage.data(); }
};

/// The named counters of one iteration, in the order first set.
class Counters {
 public:
  /// Counters an iteration may publish: a strategy's (budget has 14), a paged
  /// model's pages_* (9) and its GPU pool's in a render's row (6).
  static constexpr std::size_t kMax = 32;

  /// Sets NAME to VALUE in UNIT; a name set before in this iteration gets the
  /// new value. Throws std::invalid_argument for a name that is empty, longer
  /// than Counter::kMaxName or not of [a-z0-9_] starting with a letter, a unit
  /// longer than Counter::kMaxUnit or with a control character, or a value
  /// that is not finite; std::length_error for a counter past kMax.
  void set(std::string_view name, double value, std::string_view unit);
  /// Adds VALUE to NAME (setting it when absent); the same checks.
  void add(std::string_view name, double value, std::string_view unit);
  /// Adds every counter of OTHER to this (a scene's objects sum their
  /// strategies' counters).
  void add_all(const Counters& other);

  [[nodiscard]] std::optional<double> find(std::string_view name) const;
  [[nodiscard]] std::span<const Counter> items() const { return {items_.data(), size_}; }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  void clear() { size_ = 0; }

 private:
  Counter* slot(std::string_view name, std::string_view unit);

  std::array<Counter, kMax> items_{};
  std::size_t size_ = 0;
};

}  // namespace treecut
