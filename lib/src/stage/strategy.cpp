#include "treecut/strategy.hpp"

#include <charconv>
#include <cmath>
#include <string>

#include "treecut/error.hpp"

namespace treecut {

namespace {

// The shortest text that reads back as V: a message about 4000000001 must
// not say "4e+09 is out of range [1, 4e+09]".
std::string exact(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9007199254740992.0)
    return std::to_string(static_cast<long long>(v));
  char text[32];
  const auto [end, ec] = std::to_chars(text, text + sizeof text, v);
  return ec == std::errc() ? std::string(text, end) : std::to_string(v);
}

}  // namespace

std::string check_param(const ParamSpec& spec, double value) {
  if (!std::isfinite(value) || value < spec.min_value || value > spec.max_value)
    return spec.name + " = " + exact(value) + " is out of range [" + exact(spec.min_value) + ", " +
           exact(spec.max_value) + "]";
  if (spec.integer && value != std::floor(value))
    return spec.name + " = " + exact(value) + " must be a whole number";
  return {};
}

Strategy::Strategy(std::vector<ParamSpec> specs) : specs_(std::move(specs)) {
  values_.reserve(specs_.size());
  for (const ParamSpec& s : specs_) values_.push_back(s.default_value);
}

double Strategy::param(std::string_view name) const {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].name == name) return values_[i];
  }
  throw InputError(std::string(this->name()) + ": unknown parameter '" + std::string(name) + "'");
}

void Strategy::set_param(std::string_view name, double value) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].name != name) continue;
    if (std::string why = check_param(specs_[i], value); !why.empty()) {
      throw InputError(std::string(this->name()) + ": " + why);
    }
    if (values_[i] != value) {
      values_[i] = value;
      ++params_version_;
    }
    return;
  }
  throw InputError(std::string(this->name()) + ": unknown parameter '" + std::string(name) + "'");
}

}  // namespace treecut
