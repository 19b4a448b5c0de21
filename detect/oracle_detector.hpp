#pragma once
// A detector that knows the truth: it returns the ground-truth boxes of the frame (boxes.csv of
// a Kestrel sequence), degraded on purpose so that the dynamic filter can be evaluated against
// a detector of known quality: missed boxes, jittered corners, invented boxes, and lag.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "detect/detector.hpp"
#include "io/kestrel_sequence.hpp"

namespace kestrel::detect {

struct OracleOptions {
  double false_negative_rate = 0.0;        // probability that a true box is dropped
  double jitter_px = 0.0;                  // std. dev. of the Gaussian noise added to each box edge
  double false_positives_per_frame = 0.0;  // mean of a Poisson count of invented boxes
  std::vector<std::string> false_positive_labels = {"person"};  // drawn uniformly
  // The boxes returned for the frame at t are those of the frame at t - latency: a detector that
  // lags the image. latency_ms of the result reports it.
  Timestamp latency = 0;
  // Ground-truth frames are matched to the requested stamp within this tolerance; outside it the
  // result is empty.
  Timestamp match_tolerance = 5'000'000;  // 5 ms
  bool include_static = true;             // false: only boxes flagged `moving`
  float true_score = 1.0f;                // score of the kept true boxes
  // Used for clipping and false positives when detect() gets an empty image.
  int image_width = 640, image_height = 480;
  std::uint64_t seed = 1;
};

class OracleDetector final : public Detector {
 public:
  // Throws kestrel::Error for options outside their ranges.
  explicit OracleDetector(std::vector<io::SequenceBox> boxes, OracleOptions options = {});

  // Pixels are not looked at; only the image's size is used. The noise of a frame depends only
  // on (seed, t), so results are reproducible whatever frames are asked for and in what order.
  DetectionSet detect(const Image& image, Timestamp t) override;
  std::string name() const override { return "oracle"; }

  const OracleOptions& options() const { return options_; }

 private:
  OracleOptions options_;
  std::map<Timestamp, std::vector<io::SequenceBox>> frames_;
};

}  // namespace kestrel::detect
