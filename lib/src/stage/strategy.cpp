#include "treecut/strategy.hpp"

#include <cmath>
#include <sstream>

#include "treecut/error.hpp"

namespace treecut {

std::string check_param(const ParamSpec& spec, double value) {
  std::ostringstream why;
  if (!std::isfinite(value) || value < spec.min_value || value > spec.max_value) {
    why << spec.name << " = " << value << " is out of range [" << spec.min_value << ", "
        << spec.max_value << "]";
  } else if (spec.integer && value != std::floor(value)) {
    why << spec.name << " = " << value << " must be a whole number";
  }
  return why.str();
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
