// A terminal progress bar for long builds: drawn on stderr only when it is a
// terminal and only once the work has taken longer than a second.
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <string>
#include <string_view>

namespace treecut::cli {

class ProgressBar {
 public:
  explicit ProgressBar(std::string label)
      : label_(std::move(label)), start_(std::chrono::steady_clock::now()),
        enabled_(isatty(STDERR_FILENO) != 0) {}
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  ~ProgressBar() {
    if (drawn_) std::fputc('\n', stderr);
  }

  /// Switches to another named stage of the same job.
  void update(std::string_view label, std::size_t done, std::size_t total) {
    label_ = label;
    update(done, total);
  }

  void update(std::size_t done, std::size_t total) {
    if (!enabled_ || total == 0) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (elapsed < 1.0) return;
    const int width = 40;
    const int filled = static_cast<int>(static_cast<double>(width) * static_cast<double>(done) / static_cast<double>(total));
    std::fprintf(stderr, "\r%-10s [%.*s%*s] %3d%% %5.1fs", label_.c_str(), filled,
                 "########################################", width - filled, "",
                 static_cast<int>(100.0 * static_cast<double>(done) / static_cast<double>(total)), elapsed);
    std::fflush(stderr);
    drawn_ = true;
  }
  std::function<void(std::string_view, std::size_t, std::size_t)> callback() {
    return [this](std::string_view stage, std::size_t d, std::size_t t) { update(stage, d, t); };
  }

 private:
  std::string label_;
  std::chrono::steady_clock::time_point start_;
  bool enabled_;
  bool drawn_ = false;
};

}  // namespace treecut::cli
