// comm/pose_stream: one pose per camera frame, in stamp order, tracked where the tracker
// reported the frame and predicted (flagged) where it skipped it or is late.
#include "comm/pose_stream.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace kestrel::comm {
namespace {

constexpr Timestamp kFrame = 33'333'333;  // 30 Hz
constexpr std::uint8_t kOk = 1;

// A constant twist: 1 m/s forward while turning at 0.5 rad/s about z (an arc).
SE3 truth(Timestamp t) {
  Vec6 xi;
  xi << 1.0, 0.0, 0.0, 0.0, 0.0, 0.5;
  return SE3::exp(to_seconds(t) * xi);
}

struct Sink {
  std::vector<PoseMsg> got;
  PoseStream::Publish fn() {
    return [this](const PoseMsg& m) { got.push_back(m); };
  }
};

TEST(PoseStream, TrackedFramesGoOutAsTheyAreReported) {
  Sink sink;
  PoseStream s(sink.fn());
  for (int k = 0; k < 10; ++k) {
    const Timestamp t = k * kFrame;
    s.on_camera_frame(t, t);
    s.on_tracked(t, truth(t), kOk, t + 20'000'000);
  }
  ASSERT_EQ(sink.got.size(), 10u);
  for (int k = 0; k < 10; ++k) {
    EXPECT_EQ(sink.got[k].t, k * kFrame);
    EXPECT_EQ(sink.got[k].state, kOk);
    EXPECT_EQ(sink.got[k].seq, static_cast<std::uint32_t>(k + 1));
  }
  EXPECT_EQ(s.counts().tracked, 10u);
}

TEST(PoseStream, SkippedFramesAreInterpolatedBetweenTrackedOnes) {
  Sink sink;
  PoseStream s(sink.fn());
  // Frames 0, 3, 6 are tracked; 1, 2, 4, 5 were not fed (the tracker was busy).
  for (int k = 0; k <= 6; ++k) {
    const Timestamp t = k * kFrame;
    s.on_camera_frame(t, t);
    if (k % 3 == 0) s.on_tracked(t, truth(t), kOk, t + 10'000'000);
  }
  ASSERT_EQ(sink.got.size(), 7u);
  for (int k = 0; k <= 6; ++k) {
    const PoseMsg& m = sink.got[static_cast<std::size_t>(k)];
    EXPECT_EQ(m.t, k * kFrame);
    EXPECT_EQ(m.state, k % 3 == 0 ? kOk : kPosePredicted) << k;
    // A constant twist is interpolated exactly.
    const Vec3 p = truth(k * kFrame).translation();
    EXPECT_NEAR(m.p[0], p.x(), 1e-9) << k;
    EXPECT_NEAR(m.p[1], p.y(), 1e-9) << k;
    const Quat q = truth(k * kFrame).quaternion();
    EXPECT_NEAR(std::abs(m.q[2] * q.z() + m.q[3] * q.w()), 1.0, 1e-9) << k;
  }
  EXPECT_EQ(s.counts().interpolated, 4u);
}

TEST(PoseStream, ALateTrackerIsExtrapolatedAndNeverGoesBackInTime) {
  Sink sink;
  PoseStreamOptions o;
  o.max_wait_ns = 50'000'000;
  PoseStream s(sink.fn(), o);
  for (int k = 0; k < 2; ++k) {
    s.on_camera_frame(k * kFrame, k * kFrame);
    s.on_tracked(k * kFrame, truth(k * kFrame), kOk, k * kFrame + 1'000'000);
  }
  // Frame 2 arrives; its pose is 60 ms late: after 50 ms it is extrapolated.
  const Timestamp t2 = 2 * kFrame;
  s.on_camera_frame(t2, t2);
  s.poll(t2 + 40'000'000);
  EXPECT_EQ(sink.got.size(), 2u);  // still waiting
  s.poll(t2 + 51'000'000);
  ASSERT_EQ(sink.got.size(), 3u);
  EXPECT_EQ(sink.got[2].state, kPosePredicted);
  EXPECT_EQ(sink.got[2].t, t2);
  EXPECT_NEAR(sink.got[2].p[0], truth(t2).translation().x(), 1e-9);
  EXPECT_NEAR(sink.got[2].p[1], truth(t2).translation().y(), 1e-9);
  // Its tracked pose, arriving now, is not sent after the newer prediction of the same stamp.
  s.on_tracked(t2, truth(t2), kOk, t2 + 60'000'000);
  EXPECT_EQ(sink.got.size(), 3u);
  EXPECT_EQ(s.counts().extrapolated, 1u);
  // Long after the last tracked pose there is nothing honest to say.
  const Timestamp late = t2 + 2'000'000'000;
  s.on_camera_frame(late, late);
  s.poll(late + 100'000'000);
  EXPECT_EQ(sink.got.size(), 3u);
  EXPECT_EQ(s.counts().unsaid, 1u);
}

TEST(PoseStream, FasterCamerasAreDecimatedToTheRate) {
  Sink sink;
  PoseStream s(sink.fn());
  const Timestamp frame = 16'666'667;  // 60 Hz
  for (int k = 0; k < 60; ++k) {
    const Timestamp t = k * frame;
    s.on_camera_frame(t, t);
    s.on_tracked(t, truth(t), kOk, t);
  }
  EXPECT_EQ(sink.got.size(), 30u);
  EXPECT_EQ(s.counts().decimated, 30u);
}

TEST(PoseStream, NothingIsPredictedBeforeTheFirstTrackedPose) {
  Sink sink;
  PoseStream s(sink.fn());
  s.on_camera_frame(0, 0);
  s.on_camera_frame(kFrame, kFrame);
  s.flush();
  EXPECT_TRUE(sink.got.empty());
  EXPECT_EQ(s.counts().unsaid, 2u);
}

}  // namespace
}  // namespace kestrel::comm
