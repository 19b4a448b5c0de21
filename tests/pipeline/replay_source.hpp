#pragma once
// A measurement source that replays measurements held in memory: a rendered world fed to
// run_sequence as often as a test asks (rewind), or only from some stamp on.
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "io/measurement_source.hpp"

namespace kestrel::test {

class ReplaySource : public io::MeasurementSource {
 public:
  // Everything `from` gives, with its ground truth (taken first: a live source's truth is the
  // recent stretch of what it rendered).
  explicit ReplaySource(io::MeasurementSource& from)
      : calib_(from.calibration()), truth_(from.ground_truth()) {
    add(drain(from), 0.0);
  }
  // `items` stamped `from_s` or later, with `truth` as the ground truth (none: nullopt).
  ReplaySource(const Calibration& calib, const std::vector<Measurement>& items,
               std::optional<Trajectory> truth, double from_s = 0.0)
      : calib_(calib), truth_(std::move(truth)) {
    add(items, from_s);
  }
  static std::vector<Measurement> drain(io::MeasurementSource& from) {
    std::vector<Measurement> out;
    while (auto m = from.next()) out.push_back(std::move(*m));
    return out;
  }

  std::optional<Measurement> next() override {
    if (at_ >= items_.size()) return std::nullopt;
    return items_[at_++];
  }
  const Calibration& calibration() const override { return calib_; }
  std::optional<Trajectory> ground_truth() const override { return truth_; }
  std::size_t frame_count() const override { return frames_; }
  std::string describe() const override { return "replay"; }
  void rewind() { at_ = 0; }

 private:
  void add(const std::vector<Measurement>& items, double from_s) {
    for (const Measurement& m : items) {
      if (to_seconds(std::visit([](const auto& x) { return x.t; }, m)) < from_s) continue;
      if (!std::holds_alternative<ImuSample>(m)) ++frames_;
      items_.push_back(m);
    }
  }

  Calibration calib_;
  std::optional<Trajectory> truth_;
  std::vector<Measurement> items_;
  std::size_t frames_ = 0, at_ = 0;
};

}  // namespace kestrel::test
