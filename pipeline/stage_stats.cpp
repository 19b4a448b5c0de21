#include "pipeline/stage_stats.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace kestrel::pipeline {

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double rank = std::clamp(p, 0.0, 100.0) / 100.0 * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(rank));
  const auto hi = std::min(lo + 1, v.size() - 1);
  const double frac = rank - static_cast<double>(lo);
  return v[lo] + (v[hi] - v[lo]) * frac;
}

LatencySummary summarize(const std::vector<double>& ms) {
  LatencySummary s;
  s.count = ms.size();
  if (ms.empty()) return s;
  s.mean_ms = std::accumulate(ms.begin(), ms.end(), 0.0) / static_cast<double>(ms.size());
  s.p50_ms = percentile(ms, 50);
  s.p90_ms = percentile(ms, 90);
  s.p99_ms = percentile(ms, 99);
  s.max_ms = *std::max_element(ms.begin(), ms.end());
  return s;
}

std::vector<LatencyWindow> latency_windows(const std::vector<std::pair<double, double>>& samples,
                                           double window_s) {
  std::vector<LatencyWindow> out;
  if (samples.empty() || !(window_s > 0.0)) return out;
  double t0 = samples.front().first, t1 = t0;
  for (const auto& [t, ms] : samples) {
    t0 = std::min(t0, t);
    t1 = std::max(t1, t);
  }
  // The last window ends at the last stamp, not one past it (30 s of frames stamped 0..30 are
  // ten windows of 3 s, the frame at 30 s in the tenth).
  // The span's rounding (stamps of 1/30 s summed to 30.000000001) does not open a window.
  const auto last =
      std::max(0LL, static_cast<long long>(std::ceil((t1 - t0) / window_s - 1e-6)) - 1);
  std::map<long long, std::vector<double>> bins;
  for (const auto& [t, ms] : samples) {
    bins[std::min(last, static_cast<long long>(std::floor((t - t0) / window_s)))].push_back(ms);
  }
  for (const auto& [k, ms] : bins) {
    out.push_back(
        {static_cast<double>(k) * window_s, static_cast<double>(k + 1) * window_s, summarize(ms)});
  }
  return out;
}

void StageStats::record(const std::string& stage, double ms) {
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  std::lock_guard<std::mutex> lock(mutex_);
  Series& series = samples_[stage];
  series.ms.push_back(ms);
  series.at_s.push_back(t);
}

void StageStats::count(const std::string& counter, std::size_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  counters_[counter] += n;
}

void StageStats::set_counter(const std::string& counter, std::size_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  counters_[counter] = n;
}

std::map<std::string, LatencySummary> StageStats::summaries() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::map<std::string, LatencySummary> out;
  for (const auto& [name, series] : samples_) out[name] = summarize(series.ms);
  return out;
}

std::map<std::string, std::size_t> StageStats::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

std::vector<double> StageStats::samples(const std::string& stage) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = samples_.find(stage);
  return it == samples_.end() ? std::vector<double>{} : it->second.ms;
}

std::vector<std::pair<double, double>> StageStats::timed_samples(const std::string& stage) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::pair<double, double>> out;
  const auto it = samples_.find(stage);
  if (it == samples_.end()) return out;
  const Series& series = it->second;
  out.reserve(series.ms.size());
  for (std::size_t i = 0; i < series.ms.size(); ++i) out.emplace_back(series.at_s[i], series.ms[i]);
  return out;
}

std::string StageStats::to_json() const {
  nlohmann::json j;
  j["stages"] = nlohmann::json::object();
  for (const auto& [name, s] : summaries()) {
    j["stages"][name] = {{"count", s.count},   {"mean_ms", s.mean_ms}, {"p50_ms", s.p50_ms},
                         {"p90_ms", s.p90_ms}, {"p99_ms", s.p99_ms},   {"max_ms", s.max_ms}};
  }
  j["counters"] = counters();
  return j.dump(2);
}

}  // namespace kestrel::pipeline
