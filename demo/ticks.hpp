// Round numbers for scales a reader takes in at a glance (issue 30): the
// HUD's frame-time graph and plot.svg's axes step by 1, 2 or 5 times a power
// of ten.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace treecut::cli {

/// The smallest 1, 2 or 5 times a power of ten that is >= v; 1 for v <= 0
/// or not finite.
inline double nice_ceiling(double v) {
  if (!(v > 0.0) || !std::isfinite(v)) return 1.0;
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= v * (1.0 - 1e-12)) return m * p;
  }
  return 10.0 * p;
}

/// Tick values at a 1-2-5 step over [lo, hi] (widened to whole steps), at
/// most max_intervals + 1 of them, at least two. Values are the step times
/// an integer, so they print without rounding noise (2.5, not 2.50000001).
inline std::vector<double> nice_ticks(double lo, double hi, int max_intervals = 5) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) return {0.0, 1.0};
  if (hi < lo) std::swap(lo, hi);
  if (hi - lo < 1e-300) hi = lo + (lo == 0.0 ? 1.0 : std::abs(lo) * 0.1);
  double step = nice_ceiling((hi - lo) / std::max(1, max_intervals));
  double first = std::floor(lo / step), last = std::ceil(hi / step);
  while (last - first > max_intervals) {
    step = nice_ceiling(step * 1.5);
    first = std::floor(lo / step), last = std::ceil(hi / step);
  }
  std::vector<double> t;
  for (double k = first; k <= last + 0.5; k += 1.0) t.push_back(k * step);
  return t;
}

}  // namespace treecut::cli
