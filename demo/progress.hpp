// A terminal progress bar for long builds: drawn on stderr only when it is a
// terminal and only once the work has taken longer than a second. A ticker
// thread redraws it five times a second, so stages that report no progress of
// their own (reading, attributes) still show that they are alive.
#pragma once

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <functional>
#include <mutex>
#include <stop_token>
#include <string>
#include <string_view>
#include <thread>

namespace treecut::cli {

class ProgressBar {
 public:
  explicit ProgressBar(std::string label)
      : label_(std::move(label)), start_(std::chrono::steady_clock::now()) {
    if (isatty(STDERR_FILENO) != 0)
      ticker_ = std::jthread([this](std::stop_token stop) { tick(stop); });
  }
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  ~ProgressBar() { finish(); }

  /// Stops drawing and clears the bar's line (before printing a summary).
  void finish() {
    if (!ticker_.joinable()) return;
    ticker_.request_stop();
    wake_.notify_all();
    ticker_.join();
    if (drawn_) std::fputs("\r\033[K", stderr);  // leave the line to the summary
  }

  /// Any thread: the current stage and its progress (total 0 or 1: unknown).
  void update(std::string_view label, std::size_t done, std::size_t total) {
    std::lock_guard lock(mutex_);
    if (label_ != label) stage_start_ = std::chrono::steady_clock::now();
    label_ = label;
    done_ = done;
    total_ = total;
  }
  std::function<void(std::string_view, std::size_t, std::size_t)> callback() {
    return [this](std::string_view stage, std::size_t d, std::size_t t) { update(stage, d, t); };
  }

 private:
  void tick(std::stop_token stop) {
    std::unique_lock lock(mutex_);
    while (!stop.stop_requested()) {
      wake_.wait_for(lock, stop, std::chrono::milliseconds(200), [] { return false; });
      if (stop.stop_requested()) break;
      const double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
      if (elapsed < 1.0) continue;
      constexpr int kWidth = 40;
      const bool known = total_ > 1;
      const int filled =
          known
              ? static_cast<int>(kWidth * static_cast<double>(done_) / static_cast<double>(total_))
              : 0;
      // Within a stage that counts, its pace and what is left at it (a
      // chunked build's points and chunks: issue 44).
      char pace[64] = "";
      const double in_stage =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - stage_start_).count();
      if (known && done_ > 0 && done_ < total_ && in_stage > 1.0) {
        const double rate = double(done_) / in_stage;
        std::snprintf(pace, sizeof pace, " %zu/%zu, %s/s, %.0fs left", done_, total_,
                      human(rate).c_str(), double(total_ - done_) / rate);
      }
      std::fprintf(stderr, "\r%-10s [%.*s%*s] %s %6.1fs%s\033[K", label_.c_str(), filled,
                   "########################################", kWidth - filled, "",
                   known ? (std::to_string(100 * done_ / total_) + "%").c_str() : "...", elapsed,
                   pace);
      std::fflush(stderr);
      drawn_ = true;
    }
  }

  // 1234567 as "1.2M".
  static std::string human(double v) {
    char text[32];
    if (v >= 1e6)
      std::snprintf(text, sizeof text, "%.1fM", v / 1e6);
    else if (v >= 1e4)
      std::snprintf(text, sizeof text, "%.0fk", v / 1e3);
    else
      std::snprintf(text, sizeof text, "%.1f", v);
    return text;
  }

  std::mutex mutex_;
  std::condition_variable_any wake_;
  std::string label_;
  std::size_t done_ = 0, total_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point stage_start_ = std::chrono::steady_clock::now();
  bool drawn_ = false;
  std::jthread ticker_;  // last: started after the members it reads
};

}  // namespace treecut::cli
