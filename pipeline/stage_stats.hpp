#pragma once
// Per-stage latency records (DESIGN.md: every stage records its latency; `kestrel bench` and
// timing.json print percentiles). Thread-safe: stages on different threads record into one.
#include <chrono>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace kestrel::pipeline {

struct LatencySummary {
  std::size_t count = 0;
  double mean_ms = 0, p50_ms = 0, p90_ms = 0, p99_ms = 0, max_ms = 0;
};

// Percentile by linear interpolation between order statistics (numpy's default).
double percentile(std::vector<double> values, double p);
LatencySummary summarize(const std::vector<double>& ms);

// Latency along a run: samples (stamp in seconds, latency in ms) cut into consecutive windows of
// window_s from the first stamp, the last one closed at the last stamp; a window without
// samples is left out. A whole run's p99 hides
// a latency that grows with the map.
struct LatencyWindow {
  double from_s = 0, to_s = 0;  // stream time since the first sample
  LatencySummary latency;
};
std::vector<LatencyWindow> latency_windows(const std::vector<std::pair<double, double>>& samples,
                                           double window_s);

class StageStats {
 public:
  void record(const std::string& stage, double ms);
  void count(const std::string& counter, std::size_t n = 1);
  void set_counter(const std::string& counter, std::size_t n);
  std::map<std::string, LatencySummary> summaries() const;
  std::map<std::string, std::size_t> counters() const;
  std::vector<double> samples(const std::string& stage) const;
  // Each sample with when it was recorded (s since this StageStats was made, steady clock):
  // a live run's wall time is its stream time, so latency_windows cuts a stage along the run.
  std::vector<std::pair<double, double>> timed_samples(const std::string& stage) const;
  // {"stages": {name: {count, mean_ms, p50_ms, ...}}, "counters": {...}}
  std::string to_json() const;

 private:
  mutable std::mutex mutex_;
  struct Series {
    std::vector<double> ms;
    std::vector<double> at_s;  // when each was recorded, aligned with ms
  };
  std::map<std::string, Series> samples_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::map<std::string, std::size_t> counters_;
};

}  // namespace kestrel::pipeline
