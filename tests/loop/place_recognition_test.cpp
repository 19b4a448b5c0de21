// Place recognition on simulated revisits: the ugv-loop robot drives twice around a
// building; keyframes of the second lap must retrieve first-lap keyframes of the same place.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "loop/keyframe_database.hpp"
#include "loop/vocabulary.hpp"
#include "sim/simulator.hpp"
#include "tests/loop/loop_test_data.hpp"

namespace kestrel::loop {
namespace {

struct SimKeyframe {
  SE3 T_w_c;
  std::vector<OrbDescriptor> descriptors;
};

std::vector<SimKeyframe> render_keyframes(const std::string& scenario, double duration, int step) {
  sim::ScenarioOverrides ov;
  ov.duration = duration;
  sim::Simulator sim(sim::load_scenario(scenario, ov));
  const tracking::FeatureExtractor extractor(sim.calibration().camera);
  std::vector<SimKeyframe> out;
  for (int k = 0; k < sim.frame_count(); k += step) {
    const sim::SimFrame f = sim.render(k);
    out.push_back(
        {f.body.T_w_b * sim.calibration().T_body_camera, extractor.extract(f.color).descriptors});
  }
  return out;
}

// Same place: camera centres within `max_distance` and optical axes within `max_angle`.
bool same_place(const SE3& a, const SE3& b, double max_distance, double max_angle) {
  const Vec3 za = a.rotation().matrix().col(2);
  const Vec3 zb = b.rotation().matrix().col(2);
  return (a.translation() - b.translation()).norm() < max_distance &&
         std::acos(std::clamp(za.dot(zb), -1.0, 1.0)) < max_angle;
}

const std::vector<SimKeyframe>& ugv_keyframes() {
  static const auto keyframes = render_keyframes("ugv-loop", 40.0, 10);  // one per 1/3 s
  return keyframes;
}

// Feeds the ugv-loop keyframes in order through a KeyframeDatabase and a ConsistencyChecker
// and checks the retrievals against ground truth.
void check_place_recognition(const Vocabulary& voc, const std::string& label) {
  const auto& keyframes = ugv_keyframes();
  constexpr int kRecent = 15;  // 5 s: the robot's own recent past is not a loop
  constexpr double kPlaceDistance = 3.0;
  constexpr double kPlaceAngle = 30.0 * M_PI / 180.0;
  KeyframeDatabase db;
  ConsistencyChecker checker(3);
  int queries_with_revisit = 0, retrieved = 0, correct = 0, found_revisits = 0;
  int accepted = 0, accepted_correct = 0;
  for (int i = 0; i < static_cast<int>(keyframes.size()); ++i) {
    const BowVector bow = voc.transform(keyframes[static_cast<std::size_t>(i)].descriptors);
    const SE3& T = keyframes[static_cast<std::size_t>(i)].T_w_c;
    std::set<KeyframeId> exclude;
    for (int j = std::max(0, i - kRecent); j < i; ++j) exclude.insert(j);
    bool has_revisit = false;
    for (int j = 0; j < i - kRecent; ++j)
      has_revisit = has_revisit || same_place(T, keyframes[static_cast<std::size_t>(j)].T_w_c,
                                              kPlaceDistance, kPlaceAngle);
    const auto candidates = db.query(bow, {i - 1, i - 2}, exclude);
    queries_with_revisit += has_revisit;
    // "Correct" is looser than "revisit": a candidate a few metres off still sees the place.
    const auto is_correct = [&](const LoopCandidate& c) {
      return same_place(T, keyframes[static_cast<std::size_t>(c.id)].T_w_c, 2.0 * kPlaceDistance,
                        2.0 * kPlaceAngle);
    };
    if (std::getenv("KESTREL_LOOP_DEBUG")) {
      std::printf("q %3d revisit %d", i, has_revisit ? 1 : 0);
      for (const auto& c : candidates)
        std::printf("  [%lld %.3f %.2f %s]", static_cast<long long>(c.id), c.score, c.normalized,
                    is_correct(c) ? "ok" : "--");
      std::printf("\n");
    }
    if (!candidates.empty()) {
      ++retrieved;
      const bool ok = is_correct(candidates.front());
      correct += ok;
      found_revisits += ok && has_revisit;
    }
    std::vector<std::set<KeyframeId>> groups;
    for (const auto& c : candidates) groups.push_back({c.id - 1, c.id, c.id + 1});
    for (std::size_t a : checker.update(groups)) {
      ++accepted;
      accepted_correct += is_correct(candidates[a]);
    }
    db.add(i, bow);
  }
  const double precision = retrieved > 0 ? static_cast<double>(correct) / retrieved : 0.0;
  const double recall =
      queries_with_revisit > 0 ? static_cast<double>(found_revisits) / queries_with_revisit : 0.0;
  const double accepted_precision =
      accepted > 0 ? static_cast<double>(accepted_correct) / accepted : 0.0;
  std::printf(
      "%s: vocabulary of %zu words; %zu ugv-loop keyframes\n"
      "top-1: %d retrieved, precision %.3f; %d queries with a revisit, recall %.3f\n"
      "consistent loops (3 queries): %d accepted, precision %.3f\n",
      label.c_str(), voc.num_words(), keyframes.size(), retrieved, precision, queries_with_revisit,
      recall, accepted, accepted_precision);
  EXPECT_GT(queries_with_revisit, 20);
  EXPECT_GE(precision, 0.8);
  EXPECT_GE(recall, 0.5);
  EXPECT_GE(accepted, 5);
  EXPECT_GE(accepted_precision, 0.95);
}

TEST(PlaceRecognition, UgvLoopSecondLapFindsFirstLap) {
  // Trained on other scenes (other scenarios and real photos), so that retrieval here does not
  // rest on having clustered these very images.
  std::vector<std::vector<OrbDescriptor>> training;
  for (auto& kf : render_keyframes("office-static", 20.0, 15))
    training.push_back(std::move(kf.descriptors));
  for (auto& kf : render_keyframes("market", 20.0, 15))
    training.push_back(std::move(kf.descriptors));
  for (const auto& name : test_data::training_images())
    training.push_back(test_data::image_descriptors(name));
  check_place_recognition(Vocabulary::train(training, {.k = 10, .levels = 4}), "trained here");
}

TEST(PlaceRecognition, ShippedVocabularyWorksOnUgvLoop) {
  // config/vocabulary.kvoc, written by `kestrel vocab` from scenarios other than ugv-loop.
  const std::string path = std::string(KESTREL_SOURCE_DIR) + "/config/vocabulary.kvoc";
  const Vocabulary voc = Vocabulary::load(path);
  EXPECT_LE(voc.num_words(), 10000u);
  check_place_recognition(voc, "config/vocabulary.kvoc");
}

}  // namespace
}  // namespace kestrel::loop
