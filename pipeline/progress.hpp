#pragma once
// A progress display for long steps (rendering, running, benchmarking): on a terminal one
// line redrawn in place with a bar, the rate and the time left; when stdout is not a terminal
// (CI logs) a plain line every 10 % so the log stays readable. Header-only and free of the
// rest of Kestrel so apps and pipeline can both use it.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

namespace kestrel::pipeline {

class ProgressBar {
 public:
  // unit names what is counted ("frames", "runs"); enabled = false prints nothing.
  ProgressBar(std::size_t total, std::string unit, bool enabled = true)
      : total_(total), unit_(std::move(unit)), enabled_(enabled), tty_(isatty(1) == 1) {}

  // done: items finished so far; state: a short word shown after the figures.
  void update(std::size_t done, const std::string& state = "") {
    if (!enabled_ || total_ == 0 || finished_) return;
    done = std::min(done, total_);
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double rate = secs > 0 ? done / secs : 0.0;
    const double left = rate > 0 ? (total_ - done) / rate : 0.0;
    if (tty_) {
      constexpr int kWidth = 30;
      const int filled = static_cast<int>(kWidth * done / total_);
      // Redrawing more often than ~20 Hz only costs terminal time.
      const auto now = std::chrono::steady_clock::now();
      if (done != total_ && now - last_draw_ < std::chrono::milliseconds(50)) return;
      last_draw_ = now;
      std::printf("\r  [%s%s] %zu/%zu %s %6.1f/s %4.0fs left %-14s",
                  std::string(filled, '#').c_str(), std::string(kWidth - filled, ' ').c_str(), done,
                  total_, unit_.c_str(), rate, left, state.c_str());
      if (done == total_) std::printf("\n");
      finished_ = done == total_;
      std::fflush(stdout);
    } else if (done * 10 / total_ != last_decile_ || done == total_) {
      finished_ = done == total_;
      last_decile_ = done * 10 / total_;
      std::printf("  %zu/%zu %s, %.1f/s, %.0fs left%s%s\n", done, total_, unit_.c_str(), rate, left,
                  state.empty() ? "" : ", ", state.c_str());
      std::fflush(stdout);
    }
  }

 private:
  std::size_t total_;
  std::string unit_;
  bool enabled_, tty_;
  bool finished_ = false;
  std::size_t last_decile_ = 0;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point last_draw_{};
};

}  // namespace kestrel::pipeline
