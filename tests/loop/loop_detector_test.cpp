// Loop detection end to end on the ugv-loop revisits: BoW retrieval, consistency, guided
// matching and PnP-RANSAC against the candidate's depth points, checked against the truth.
#include "loop/loop_detector.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "sim/simulator.hpp"
#include "tests/loop/loop_test_data.hpp"

namespace kestrel::loop {
namespace {

struct Rendered {
  std::vector<PlaceView> views;
  std::vector<SE3> truth;  // T_w_c
  PinholeCamera camera;
};

const Rendered& ugv_views() {
  static const Rendered r = [] {
    Rendered out;
    sim::ScenarioOverrides ov;
    ov.duration = 40.0;
    sim::Simulator sim(sim::load_scenario("ugv-loop", ov));
    out.camera = sim.calibration().camera;
    const tracking::FeatureExtractor extractor(out.camera);
    for (int k = 0, id = 0; k < sim.frame_count(); k += 10, ++id) {
      const sim::SimFrame f = sim.render(k);
      const tracking::FrameFeatures ff =
          extractor.extract(f.color, nullptr, &f.depth, sim.calibration().depth_scale);
      PlaceView v;
      v.id = id;
      v.descriptors = ff.descriptors;
      for (std::size_t i = 0; i < ff.size(); ++i) {
        v.keypoints_un.push_back(ff.keypoints[i].un);
        v.points_c.push_back(ff.points_c[i]);
        v.has_point.push_back(ff.has_depth(i) ? 1 : 0);
      }
      if (id >= 1) v.neighbours.push_back(id - 1);
      if (id >= 2) v.neighbours.push_back(id - 2);
      out.truth.push_back(f.body.T_w_b * sim.calibration().T_body_camera);
      out.views.push_back(std::move(v));
    }
    return out;
  }();
  return r;
}

TEST(LoopDetector, ClosesUgvLoopRevisitsWithAccurateRelativePose) {
  const Vocabulary voc =
      Vocabulary::load(std::string(KESTREL_SOURCE_DIR) + "/config/vocabulary.kvoc");
  const Rendered& r = ugv_views();
  LoopDetector detector(voc, r.camera);
  int loops = 0, wrong = 0, aliased = 0;
  double max_t_err = 0.0, max_r_err = 0.0;
  for (std::size_t i = 0; i < r.views.size(); ++i) {
    const auto m = detector.process(r.views[i]);
    if (!m) continue;
    ++loops;
    const SE3 truth_rel = r.truth[static_cast<std::size_t>(m->match)].inverse() * r.truth[i];
    const Vec6 err = (truth_rel.inverse() * m->T_match_query).log();
    const double t_err = (truth_rel.translation() - m->T_match_query.translation()).norm();
    const double r_err = err.tail<3>().norm();
    const double dist =
        (r.truth[static_cast<std::size_t>(m->match)].translation() - r.truth[i].translation())
            .norm();
    if (dist > 6.0) ++wrong;
    // The ground's tiles repeat every 2.5 m: PnP can lock onto a pose shifted by whole
    // periods with many inliers. Counted separately; the pose graph must withstand it.
    if (t_err > 0.5) {
      ++aliased;
    } else {
      max_t_err = std::max(max_t_err, t_err);
      max_r_err = std::max(max_r_err, r_err);
    }
    std::printf(
        "loop %lld -> %lld: %d/%d inliers, score %.3f, places %.2f m apart, pose error "
        "%.3f m %.2f deg\n",
        static_cast<long long>(m->query), static_cast<long long>(m->match), m->inliers, m->matches,
        m->score, dist, t_err, r_err * 180.0 / M_PI);
  }
  std::printf(
      "%d loops closed, %d at the wrong place, %d aliased by periodic texture; max "
      "relative-pose error of the others %.3f m, %.2f deg\n",
      loops, wrong, aliased, max_t_err, max_r_err * 180.0 / M_PI);
  EXPECT_GE(loops - aliased, 10);
  EXPECT_LE(aliased, 1);
  EXPECT_EQ(wrong, 0);
  EXPECT_LT(max_t_err, 0.1);
  EXPECT_LT(max_r_err, 1.0 * M_PI / 180.0);
}

TEST(LoopDetector, RelocalizesASecondLapFrameAgainstTheFirstLap) {
  const Vocabulary voc =
      Vocabulary::load(std::string(KESTREL_SOURCE_DIR) + "/config/vocabulary.kvoc");
  const Rendered& r = ugv_views();
  LoopDetector detector(voc, r.camera);
  const std::size_t lap = 60;  // 20 s at 3 keyframes per second
  for (std::size_t i = 0; i < lap; ++i) detector.process(r.views[i]);
  int relocalized = 0, tried = 0;
  for (std::size_t i = lap + 5; i < r.views.size(); i += 10) {
    ++tried;
    PlaceView lost = r.views[i];
    lost.neighbours.clear();
    const auto m = detector.relocalize(lost);
    if (!m) continue;
    const SE3 T_w_c = r.truth[static_cast<std::size_t>(m->match)] * m->T_match_query;
    const double err = (T_w_c.translation() - r.truth[i].translation()).norm();
    EXPECT_LT(err, 0.1) << "frame " << i;
    relocalized += err < 0.1;
  }
  std::printf("relocalized %d of %d second-lap frames\n", relocalized, tried);
  EXPECT_GE(relocalized, tried - 1);
}

}  // namespace
}  // namespace kestrel::loop
