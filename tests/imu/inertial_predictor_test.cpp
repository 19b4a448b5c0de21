// The predictor against the analytic motion: velocity and biases from noisy visual fixes, and
// dead reckoning through a gap as a lost track needs it.
#include "imu/inertial_predictor.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include "imu_test_motion.hpp"

namespace kestrel::imu {
namespace {

using test::Motion;

constexpr double kFrameRate = 30.0;
constexpr double kImuRate = 200.0;

SE3 noisy_fix(const Motion& m, double t, double sigma_p, double sigma_r, std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Vec3 dp(n(rng), n(rng), n(rng));
  const Vec3 dr(n(rng), n(rng), n(rng));
  return SE3(m.rotation(t) * SO3::exp(sigma_r * dr), m.position(t) + sigma_p * dp);
}

// Feeds fixes at frame rate over [0, t_end] and returns the predictor. `world`: the fixes are
// given in a world turned by it (a camera-first world, not the z-up one).
// `options`: the predictor's; `fix_error`: an attitude error of every fix at t (a track's slow
// drift, unlike the white noise of sigma_r).
InertialPredictor run(const Motion& m, double t_end, double sigma_p, double sigma_r, unsigned seed,
                      double imu_until, const SO3& world = SO3(),
                      const InertialPredictorOptions& options = {},
                      const std::function<SO3(double)>& fix_error = {}) {
  InertialPredictor p(options);
  std::mt19937 rng(seed);
  std::vector<ImuSample> imu = m.samples(0.0, imu_until, kImuRate);
  test::add_noise(imu, ImuNoise{}, 1.0 / kImuRate, rng);
  // Samples arrive as the System hands them over: up to each frame's stamp, with one
  // interpolated to exactly that stamp (pipeline::ImuBuffer::between), then the rest.
  std::size_t fed = 0;
  auto feed_until = [&](double t) {
    std::size_t n = fed;
    const Timestamp ts = from_seconds(t);
    while (n < imu.size() && imu[n].t <= ts) ++n;
    std::vector<ImuSample> batch(imu.begin() + static_cast<long>(fed),
                                 imu.begin() + static_cast<long>(n));
    if (n > 0 && n < imu.size() && imu[n - 1].t < ts) {
      batch.push_back(interpolate(imu[n - 1], imu[n], ts));
    }
    p.add_samples(batch);
    fed = n;
  };
  for (int f = 0; f / kFrameRate <= t_end; ++f) {
    const double t = f / kFrameRate;
    feed_until(t);
    SE3 fix = noisy_fix(m, t, sigma_p, sigma_r, rng);
    if (fix_error) fix = SE3(fix.so3() * fix_error(t), fix.translation());
    p.add_fix(from_seconds(t), SE3(world, Vec3::Zero()) * fix);
  }
  feed_until(imu_until);
  return p;
}

TEST(InertialPredictor, NoPredictionBeforeTheWindowFills) {
  Motion m;
  InertialPredictor p;
  p.add_samples(m.samples(0.0, 1.0, kImuRate));
  p.add_fix(0, SE3(m.rotation(0.0), m.position(0.0)));
  EXPECT_FALSE(p.predict(from_seconds(0.033)).has_value());
}

TEST(InertialPredictor, VelocityFromCentimetreFixes) {
  const Motion m;
  const double t_end = 2.0;
  InertialPredictor p = run(m, t_end, 0.01, 1e-3, 1, 5.0);
  ASSERT_TRUE(p.velocity().has_value());
  const double t_last = std::floor(t_end * kFrameRate) / kFrameRate;
  const double err = (*p.velocity() - m.velocity(t_last)).norm();
  // Differencing two fixes a frame apart would be off by ~0.4 m/s here.
  EXPECT_LT(err, 0.05) << "velocity error " << err << " m/s";
}

// A world whose gravity is learnt after the first fixes (EuRoC's camera-first world): the
// velocity fitted under the assumed z-up gravity is off by metres per second, and set_gravity
// fits it again. Before, the System's first predictions carried a body at rest off at 4 m/s.
TEST(InertialPredictor, SetGravityFitsTheVelocityAgain) {
  const Motion m;
  const SO3 world = SO3::exp(Vec3(0.4, -1.3, 0.2));
  const double t_end = 2.0;
  InertialPredictor p = run(m, t_end, 0.01, 1e-3, 3, 5.0, world);
  const double t_last = std::floor(t_end * kFrameRate) / kFrameRate;
  const Vec3 v_true = world * m.velocity(t_last);
  ASSERT_TRUE(p.velocity().has_value());
  EXPECT_GT((*p.velocity() - v_true).norm(), 1.0) << "the assumed gravity should not fit";
  p.set_gravity(world * m.gravity);
  ASSERT_TRUE(p.velocity().has_value());
  EXPECT_LT((*p.velocity() - v_true).norm(), 0.05) << p.velocity()->transpose();
  EXPECT_THROW(p.set_gravity(Vec3(0.0, std::nan(""), 0.0)), std::invalid_argument);
}

TEST(InertialPredictor, SetGyroBiasRestartsTheEstimate) {
  InertialPredictor p;
  p.set_gyro_bias(Vec3(0.001, 0.02, 0.08), 0.002);
  EXPECT_TRUE(p.bias().gyro.isApprox(Vec3(0.001, 0.02, 0.08)));
  EXPECT_NEAR(p.gyro_bias_sigma(), 0.002, 1e-12);
  EXPECT_THROW(p.set_gyro_bias(Vec3::Zero(), 0.0), std::invalid_argument);
  EXPECT_THROW(p.set_gyro_bias(Vec3(std::nan(""), 0.0, 0.0), 0.01), std::invalid_argument);
}

TEST(InertialPredictor, EstimatesBothBiases) {
  Motion m;
  m.gyro_bias = Vec3(0.01, -0.02, 0.015);
  m.acc_bias = Vec3(0.08, -0.05, 0.1);
  // Fixes with white noise only: the window's own covariance is the truth, no floor.
  InertialPredictorOptions o;
  o.gyro_bias_window_floor = 0.0;
  InertialPredictor p = run(m, 6.0, 0.005, 5e-4, 2, 8.0, SO3(), o);
  EXPECT_LT((p.bias().gyro - m.gyro_bias).norm(), 0.003) << p.bias().gyro.transpose();
  EXPECT_LT((p.bias().acc - m.acc_bias).norm(), 0.04) << p.bias().acc.transpose();
}

// A track whose attitude slides 2 degrees over its first 2 s (a take-off over bare ground)
// and then holds: the window fit reads that slide as a 0.017 rad/s gyro bias, white fix noise
// would let it in whole, and the gyro prior would then hold every later frame to it. With the
// floor, the estimate moves a third of the way; a true bias is still learnt, more slowly.
TEST(InertialPredictor, ASlidingTrackDoesNotSetTheGyroBias) {
  const Motion m;  // no gyro bias
  const Vec3 axis = Vec3(1.0, -2.0, 0.5).normalized();
  const auto slide = [&](double t) { return SO3::exp(axis * (0.035 * std::min(t, 2.0) / 2.0)); };
  InertialPredictorOptions white;
  white.gyro_bias_window_floor = 0.0;
  const InertialPredictor without = run(m, 2.2, 0.005, 5e-4, 4, 4.0, SO3(), white, slide);
  const InertialPredictor with = run(m, 2.2, 0.005, 5e-4, 4, 4.0, SO3(), {}, slide);
  std::printf("gyro bias read from a 2 degree slide: %.4f rad/s without the floor, %.4f with\n",
              without.bias().gyro.norm(), with.bias().gyro.norm());
  EXPECT_GT(without.bias().gyro.norm(), 0.012) << without.bias().gyro.transpose();
  EXPECT_LT(with.bias().gyro.norm(), 0.5 * without.bias().gyro.norm())
      << with.bias().gyro.transpose();
  // A true bias, with honest fixes, over 30 s.
  Motion biased;
  biased.gyro_bias = Vec3(0.01, -0.02, 0.015);
  const InertialPredictor learnt = run(biased, 30.0, 0.005, 5e-4, 5, 32.0);
  EXPECT_LT((learnt.bias().gyro - biased.gyro_bias).norm(), 0.006)
      << learnt.bias().gyro.transpose();
}

TEST(InertialPredictor, DeadReckonsThroughAOneSecondGap) {
  Motion m;
  m.gyro_bias = Vec3(0.005, 0.0, -0.005);
  m.acc_bias = Vec3(0.03, 0.02, -0.04);
  const double t_fix = 4.0;
  InertialPredictor p = run(m, t_fix, 0.005, 5e-4, 3, 8.0);
  const double t_last = std::floor(t_fix * kFrameRate) / kFrameRate;
  const auto pred = p.predict(from_seconds(t_last + 1.0));
  ASSERT_TRUE(pred.has_value());
  EXPECT_NEAR(pred->since_fix_s, 1.0, 1e-9);
  const double e_p = (pred->T_w_b.translation() - m.position(t_last + 1.0)).norm();
  const double e_r = (pred->T_w_b.so3().inverse() * m.rotation(t_last + 1.0)).angle();
  // A constant-velocity guess over this second of curved motion is off by about a metre.
  const double e_cv = (m.position(t_last) + m.velocity(t_last) - m.position(t_last + 1.0)).norm();
  EXPECT_LT(e_p, 0.1) << "position error " << e_p << " m (constant velocity: " << e_cv << ")";
  EXPECT_LT(e_r, 0.01) << "rotation error " << e_r << " rad";
  EXPECT_GT(e_cv, 0.3);
}

TEST(InertialPredictor, RefusesBeyondTheImuAndTheGap) {
  const Motion m;
  InertialPredictor p = run(m, 2.0, 0.01, 1e-3, 4, 3.0);
  const double t_last = std::floor(2.0 * kFrameRate) / kFrameRate;
  EXPECT_TRUE(p.predict(from_seconds(t_last + 0.5)).has_value());
  EXPECT_FALSE(p.predict(from_seconds(3.5))) << "the IMU ends at 3 s";
  InertialPredictor q = run(m, 2.0, 0.01, 1e-3, 4, 8.0);
  EXPECT_FALSE(q.predict(from_seconds(t_last + 2.5))) << "longer than max_gap_s";
  q.clear_fixes();
  EXPECT_FALSE(q.predict(from_seconds(t_last + 0.1)));
}

// A relocalization during a short loss: the predictor restarts from the relocalized pose with
// the velocity it carried, and predicts the very next frame (clear_fixes would wait for a new
// velocity window), as well as from a fresh fix of the same pose.
TEST(InertialPredictor, ReanchorKeepsPredictingWithTheCarriedVelocity) {
  const Motion m;
  InertialPredictor p = run(m, 2.0, 0.005, 5e-4, 5, 5.0);
  const double t_reloc = 2.5;  // half a second without fixes, then a (true) relocalized pose
  const auto carried = p.predict(from_seconds(t_reloc));
  ASSERT_TRUE(carried.has_value());
  const SE3 reloc(m.rotation(t_reloc), m.position(t_reloc));
  // The velocity was fitted at the last fix; the reanchor carries it on without a new fit.
  ASSERT_TRUE(p.velocity_fitted_at().has_value());
  const Timestamp fitted_at = *p.velocity_fitted_at();
  EXPECT_LE(fitted_at, from_seconds(2.0));
  EXPECT_GT(fitted_at, from_seconds(2.0 - 2.0 / kFrameRate));
  p.reanchor(from_seconds(t_reloc), reloc, carried->v_w);
  ASSERT_TRUE(p.velocity_fitted_at().has_value());
  EXPECT_EQ(*p.velocity_fitted_at(), fitted_at) << "a reanchor is no fit";
  const double t_next = t_reloc + 1.0 / kFrameRate;
  const auto next = p.predict(from_seconds(t_next));
  ASSERT_TRUE(next.has_value());
  EXPECT_NEAR(next->since_fix_s, 1.0 / kFrameRate, 1e-9);
  EXPECT_LT((next->T_w_b.translation() - m.position(t_next)).norm(), 0.01);
  // Fixes after the anchor are taken as usual.
  p.add_fix(from_seconds(t_next), SE3(m.rotation(t_next), m.position(t_next)));
  EXPECT_TRUE(p.predict(from_seconds(t_next + 1.0 / kFrameRate)).has_value());
  InertialPredictor q = run(m, 2.0, 0.005, 5e-4, 5, 5.0);
  q.clear_fixes();
  EXPECT_FALSE(q.velocity_fitted_at().has_value());
  q.add_fix(from_seconds(t_reloc), reloc);
  EXPECT_FALSE(q.predict(from_seconds(t_next))) << "a single fix gives no velocity";
  InertialPredictor bad = run(m, 2.0, 0.005, 5e-4, 5, 5.0);
  bad.reanchor(from_seconds(t_reloc), reloc, Vec3::Constant(std::nan("")));
  EXPECT_FALSE(bad.predict(from_seconds(t_next)));
}

// Long after the pose is refused (max_gap_s), the gyro alone still knows which way the body
// faces: what tells a look-alike place seen the other way round from the real one.
TEST(InertialPredictor, AttitudeOutlivesThePrediction) {
  Motion m;
  m.gyro_bias = Vec3(0.004, -0.003, 0.005);
  const double t_fix = 4.0;
  // White-noise fixes: their windows are trusted as they are (no floor), so the bias is known
  // after these 4 s; what is tested is how long the attitude lasts on it.
  InertialPredictorOptions o;
  o.gyro_bias_window_floor = 0.0;
  InertialPredictor p = run(m, t_fix, 0.005, 5e-4, 6, t_fix + 8.0, SO3(), o);
  const double t_last = std::floor(t_fix * kFrameRate) / kFrameRate;
  EXPECT_FALSE(p.predict(from_seconds(t_last + 8.0))) << "past max_gap_s";
  const auto a = p.attitude();
  ASSERT_TRUE(a.has_value());
  EXPECT_NEAR(a->since_fix_s, 8.0, 0.01);
  const double t = to_seconds(a->t);
  const double e = (a->R_w_b.inverse() * m.rotation(t)).angle();
  // Uncorrected, the bias alone would turn the body by ~0.06 rad over these 8 s.
  EXPECT_LT(e, 0.02) << "attitude error " << e << " rad after 8 s on the gyro";
  // A fix resets it.
  p.add_fix(from_seconds(t + 0.01), SE3(m.rotation(t + 0.01), m.position(t + 0.01)));
  ASSERT_TRUE(p.attitude().has_value());
  EXPECT_NEAR(p.attitude()->since_fix_s, 0.0, 1e-12);
}

TEST(InertialPredictor, NoAttitudeBeforeAFix) {
  const Motion m;
  InertialPredictor p;
  p.add_samples(m.samples(0.0, 1.0, kImuRate));
  EXPECT_FALSE(p.attitude().has_value());
}

TEST(InertialPredictor, IgnoresNonFiniteInput) {
  const Motion m;
  InertialPredictor p = run(m, 1.5, 0.01, 1e-3, 5, 3.0);
  const std::size_t n = p.fixes();
  SE3 bad(m.rotation(1.6), Vec3(std::nan(""), 0.0, 0.0));
  p.add_fix(from_seconds(1.6), bad);
  EXPECT_EQ(p.fixes(), n);
  // An infinite reading between two good ones: integrated, it would poison the pose.
  ImuSample inf = m.sample(3.1);
  inf.acc.x() = std::numeric_limits<double>::infinity();
  const ImuSample after = m.sample(3.2);
  p.add_samples(std::span<const ImuSample>(&inf, 1));
  p.add_samples(std::span<const ImuSample>(&after, 1));
  const auto pred = p.predict(from_seconds(3.15));
  ASSERT_TRUE(pred.has_value()) << "the infinite sample must be dropped, not integrated";
  EXPECT_TRUE(pred->T_w_b.is_finite());
}

}  // namespace
}  // namespace kestrel::imu
