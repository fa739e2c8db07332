// Named counters of an iteration (treecut/counters.hpp).
#include "treecut/counters.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace treecut {

namespace {

void check(std::string_view name, double value, std::string_view unit) {
  const auto bad = [&](const std::string& why) {
    throw std::invalid_argument("counter '" + std::string(name.substr(0, Counter::kMaxName + 1)) +
                                "': " + why);
  };
  if (name.empty() || name.size() > Counter::kMaxName)
    bad("a name is 1 to " + std::to_string(Counter::kMaxName) + " characters");
  if (name.front() < 'a' || name.front() > 'z') bad("a name starts with a letter a-z");
  if (!std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
      })) {
    bad("a name is of a-z, 0-9 and _ (a stats.csv column)");
  }
  if (unit.size() > Counter::kMaxUnit)
    bad("a unit is at most " + std::to_string(Counter::kMaxUnit) + " characters");
  if (std::any_of(unit.begin(), unit.end(), [](char c) {
        return static_cast<unsigned char>(c) < 0x20 || c == 0x7f || c == ',' || c == '"';
      })) {
    bad("a unit holds no control character, comma or quote");
  }
  if (!std::isfinite(value)) bad("the value is not finite");
}

}  // namespace

Counter* Counters::slot(std::string_view name, std::string_view unit) {
  for (std::size_t i = 0; i < size_; ++i) {
    if (items_[i].name() == name) return &items_[i];
  }
  if (size_ == kMax) {
    throw std::length_error("counter '" + std::string(name) + "': more than " +
                            std::to_string(kMax) + " counters in one iteration");
  }
  Counter& c = items_[size_++];
  c = Counter{};
  std::copy(name.begin(), name.end(), c.name_storage.begin());
  std::copy(unit.begin(), unit.end(), c.unit_storage.begin());
  return &c;
}

void Counters::set(std::string_view name, double value, std::string_view unit) {
  check(name, value, unit);
  slot(name, unit)->value = value;
}

void Counters::add(std::string_view name, double value, std::string_view unit) {
  check(name, value, unit);
  slot(name, unit)->value += value;
}

void Counters::add_all(const Counters& other) {
  for (const Counter& c : other.items()) slot(c.name(), c.unit())->value += c.value;
}

std::optional<double> Counters::find(std::string_view name) const {
  for (const Counter& c : items()) {
    if (c.name() == name) return c.value;
  }
  return std::nullopt;
}

}  // namespace treecut
