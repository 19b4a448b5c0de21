#include "detect/oracle_detector.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/error.hpp"
#include "detect/class_names.hpp"

namespace kestrel::detect {

namespace {

// splitmix64: spreads (seed, stamp) over the whole state so neighbouring stamps give unrelated
// streams.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

Detection make_detection(const std::string& label, float score, double x0, double y0, double x1,
                         double y1, double width, double height) {
  Detection d;
  d.label = canonical_coco_label(label);
  d.class_id = coco_class_id(d.label);
  d.score = score;
  d.x_min = static_cast<float>(std::clamp(std::min(x0, x1), 0.0, width));
  d.x_max = static_cast<float>(std::clamp(std::max(x0, x1), 0.0, width));
  d.y_min = static_cast<float>(std::clamp(std::min(y0, y1), 0.0, height));
  d.y_max = static_cast<float>(std::clamp(std::max(y0, y1), 0.0, height));
  return d;
}

}  // namespace

OracleDetector::OracleDetector(std::vector<io::SequenceBox> boxes, OracleOptions options)
    : options_(std::move(options)) {
  const std::string where = "OracleOptions";
  const OracleOptions& o = options_;
  if (!(o.false_negative_rate >= 0.0 && o.false_negative_rate <= 1.0)) {
    throw Error::at(where, 0, "false_negative_rate", "must be in [0, 1]");
  }
  if (!(o.jitter_px >= 0.0 && std::isfinite(o.jitter_px))) {
    throw Error::at(where, 0, "jitter_px", "must be a finite value >= 0");
  }
  if (!(o.false_positives_per_frame >= 0.0 && std::isfinite(o.false_positives_per_frame))) {
    throw Error::at(where, 0, "false_positives_per_frame", "must be a finite value >= 0");
  }
  if (o.false_positives_per_frame > 0.0 && o.false_positive_labels.empty()) {
    throw Error::at(where, 0, "false_positive_labels", "must not be empty with false positives");
  }
  if (o.match_tolerance < 0) throw Error::at(where, 0, "match_tolerance", "must be >= 0");
  if (o.image_width <= 0 || o.image_height <= 0) {
    throw Error::at(where, 0, "image_width/image_height", "must be positive");
  }
  for (io::SequenceBox& b : boxes) frames_[b.t].push_back(std::move(b));
}

DetectionSet OracleDetector::detect(const Image& image, Timestamp t) {
  const OracleOptions& o = options_;
  DetectionSet out;
  out.t = t;
  out.latency_ms = static_cast<double>(o.latency) * 1e-6;
  const double width = image.empty() ? o.image_width : image.width;
  const double height = image.empty() ? o.image_height : image.height;

  std::mt19937_64 rng(mix(o.seed ^ mix(static_cast<std::uint64_t>(t))));
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, o.jitter_px > 0 ? o.jitter_px : 1.0);

  // The ground-truth frame nearest to t - latency, if close enough.
  const Timestamp source = t - o.latency;
  const std::vector<io::SequenceBox>* truth = nullptr;
  auto it = frames_.lower_bound(source);
  Timestamp best = o.match_tolerance + 1;
  if (it != frames_.end() && it->first - source < best) {
    best = it->first - source;
    truth = &it->second;
  }
  if (it != frames_.begin() && source - std::prev(it)->first < best) {
    truth = &std::prev(it)->second;
  }

  if (truth) {
    for (const io::SequenceBox& b : *truth) {
      if (!o.include_static && !b.moving) continue;
      // Always draw, so one box's fate does not shift the noise of the others.
      const bool dropped = uniform(rng) < o.false_negative_rate;
      double e[4] = {0, 0, 0, 0};
      if (o.jitter_px > 0) {
        for (double& v : e) v = noise(rng);
      }
      if (dropped) continue;
      Detection d = make_detection(b.label, o.true_score, b.x_min + e[0], b.y_min + e[1],
                                   b.x_max + e[2], b.y_max + e[3], width, height);
      if (d.width() > 0 && d.height() > 0) out.boxes.push_back(std::move(d));
    }
  }

  if (o.false_positives_per_frame > 0) {
    std::poisson_distribution<int> count(o.false_positives_per_frame);
    const int n = count(rng);
    std::uniform_int_distribution<std::size_t> pick(0, o.false_positive_labels.size() - 1);
    for (int i = 0; i < n; ++i) {
      // Sizes between 5 % and 40 % of the image side, anywhere inside it.
      const double w = width * (0.05 + 0.35 * uniform(rng));
      const double h = height * (0.05 + 0.35 * uniform(rng));
      const double x = (width - w) * uniform(rng);
      const double y = (height - h) * uniform(rng);
      const auto score = static_cast<float>(0.25 + 0.5 * uniform(rng));
      out.boxes.push_back(make_detection(o.false_positive_labels[pick(rng)], score, x, y, x + w,
                                         y + h, width, height));
    }
  }
  return out;
}

}  // namespace kestrel::detect
