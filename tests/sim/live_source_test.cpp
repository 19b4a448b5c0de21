// The live feed is the recorded sequence without the disk: the same measurements in the same
// order, the same pixels, IMU and ground truth as `kestrel sim` writes and the reader reads.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "io/kestrel_sequence.hpp"
#include "sim/live_source.hpp"
#include "sim/sequence_recorder.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::sim {
namespace {

// Jitter and drops on, so the stream's stamps and gaps are the sensor's, not k / fps.
Scenario jittery_market() {
  ScenarioOverrides ov;
  ov.duration = 0.6;
  Scenario s = load_scenario("market", ov);
  s.sensor.jitter = 0.002;
  s.sensor.drop_rate = 0.2;
  return s;
}

bool same_pixels(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.channels == b.channels &&
         a.type == b.type && !a.empty() && *a.data == *b.data;
}

TEST(LiveSource, StreamsWhatTheRecorderWritesAndTheReaderReads) {
  const auto dir = test::temp_dir("live_source_seq");
  Simulator rec(jittery_market());
  const RecordStats st = record_sequence(rec, dir.string());
  ASSERT_LT(st.written, st.frames);  // some frames dropped

  auto disk = io::open_kestrel_sequence(dir.string());
  LiveSource live(jittery_market());
  EXPECT_EQ(live.frame_count(), disk->frame_count());
  EXPECT_EQ(live.frame_count(), static_cast<std::size_t>(st.written));

  std::size_t frames = 0, imu = 0;
  while (true) {
    auto a = live.next();
    auto b = disk->next();
    ASSERT_EQ(a.has_value(), b.has_value()) << "after " << frames << " frames, " << imu << " IMU";
    if (!a) break;
    ASSERT_EQ(a->index(), b->index());
    ASSERT_EQ(stamp_of(*a), stamp_of(*b));
    if (const auto* fa = std::get_if<RgbdFrame>(&*a)) {
      const auto& fb = std::get<RgbdFrame>(*b);
      EXPECT_TRUE(same_pixels(fa->color, fb.color)) << "frame " << frames;
      EXPECT_TRUE(same_pixels(fa->depth, fb.depth)) << "frame " << frames;
      EXPECT_DOUBLE_EQ(fa->depth_scale, fb.depth_scale);
      // The mover mask of a frame just streamed is the one written to dynamic/.
      EXPECT_TRUE(same_pixels(live.truth_mask(fa->t), io::read_dynamic_mask(dir.string(), fa->t)))
          << "frame " << frames;
      ++frames;
    } else {
      const auto& ia = std::get<ImuSample>(*a);
      const auto& ib = std::get<ImuSample>(*b);
      EXPECT_LT((ia.gyro - ib.gyro).norm(), 1e-6);  // imu.csv keeps 9 significant digits
      EXPECT_LT((ia.acc - ib.acc).norm(), 1e-5);
      ++imu;
    }
  }
  EXPECT_EQ(frames, live.frame_count());
  EXPECT_EQ(imu, static_cast<std::size_t>(st.imu_samples));

  const auto ga = live.ground_truth(), gb = disk->ground_truth();
  ASSERT_TRUE(ga && gb);
  ASSERT_EQ(ga->size(), gb->size());
  for (std::size_t i = 0; i < ga->size(); ++i) {
    EXPECT_NEAR(ga->stamps[i], gb->stamps[i], 1e-9);
    EXPECT_LT((ga->poses[i].translation() - gb->poses[i].translation()).norm(), 1e-6);
  }
  EXPECT_TRUE(live.truth_mask(12345).empty());  // never streamed
}

TEST(LiveSource, OldMasksAgeOutOfTheWindow) {
  LiveSource live(jittery_market(), 2);
  std::vector<Timestamp> stamps;
  while (auto m = live.next()) {
    if (const auto* f = std::get_if<RgbdFrame>(&*m)) stamps.push_back(f->t);
  }
  ASSERT_GE(stamps.size(), 4u);
  EXPECT_FALSE(live.truth_mask(stamps.back()).empty());
  EXPECT_FALSE(live.truth_mask(stamps[stamps.size() - 2]).empty());
  EXPECT_TRUE(live.truth_mask(stamps.front()).empty());
}

}  // namespace
}  // namespace kestrel::sim
