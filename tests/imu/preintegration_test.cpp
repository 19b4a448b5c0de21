#include "imu/preintegration.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <random>

#include "tests/imu/imu_test_motion.hpp"

namespace kestrel::imu {
namespace {

using test::Motion;

struct Deltas {
  SO3 R;
  Vec3 v = Vec3::Zero();
  Vec3 p = Vec3::Zero();
};

// Reference: RK4 at `rate_hz` on the continuous readings (minus `bias`), in the start frame.
Deltas rk4_reference(const Motion& m, double t0, double t1, const ImuBias& bias,
                     double rate_hz = 10000.0) {
  struct D {
    Quat q;
    Vec3 v, p;
  };
  auto deriv = [&](double t, const D& s) {
    const Vec3 w = m.true_gyro(t) + m.gyro_bias - bias.gyro;
    const Vec3 a = m.true_acc(t) + m.acc_bias - bias.acc;
    D d;
    d.q.coeffs() = (s.q * Quat(0.0, 0.5 * w.x(), 0.5 * w.y(), 0.5 * w.z())).coeffs();
    d.v = s.q.normalized() * a;
    d.p = s.v;
    return d;
  };
  auto add = [](const D& s, const D& d, double h) {
    D o;
    o.q.coeffs() = s.q.coeffs() + h * d.q.coeffs();
    o.v = s.v + h * d.v;
    o.p = s.p + h * d.p;
    return o;
  };
  const int n = static_cast<int>(std::lround((t1 - t0) * rate_hz));
  const double h = (t1 - t0) / n;
  D s{Quat::Identity(), Vec3::Zero(), Vec3::Zero()};
  for (int k = 0; k < n; ++k) {
    const double t = t0 + k * h;
    const D k1 = deriv(t, s);
    const D k2 = deriv(t + 0.5 * h, add(s, k1, 0.5 * h));
    const D k3 = deriv(t + 0.5 * h, add(s, k2, 0.5 * h));
    const D k4 = deriv(t + h, add(s, k3, h));
    s.q.coeffs() +=
        h / 6.0 * (k1.q.coeffs() + 2 * k2.q.coeffs() + 2 * k3.q.coeffs() + k4.q.coeffs());
    s.v += h / 6.0 * (k1.v + 2 * k2.v + 2 * k3.v + k4.v);
    s.p += h / 6.0 * (k1.p + 2 * k2.p + 2 * k3.p + k4.p);
    s.q.normalize();
  }
  return {SO3(s.q), s.v, s.p};
}

Preintegration preintegrate(const Motion& m, double t0, double t1, double rate_hz,
                            const ImuBias& bias = {}) {
  const std::vector<ImuSample> s = m.samples(t0, t1, rate_hz);
  Preintegration pre(bias, ImuNoise{});
  EXPECT_TRUE(pre.integrate(s, from_seconds(t0), from_seconds(t1)));
  return pre;
}

struct Errors {
  double R, v, p;
};
Errors errors(const Preintegration& pre, const Deltas& ref) {
  return {(pre.delta_R().inverse() * ref.R).log().norm(), (pre.delta_v() - ref.v).norm(),
          (pre.delta_p() - ref.p).norm()};
}

TEST(Preintegration, MatchesRk4ReferenceAt200Hz) {
  Motion m;
  m.gyro_bias = Vec3(0.01, -0.02, 0.015);
  m.acc_bias = Vec3(0.05, 0.1, -0.08);
  const ImuBias bias{m.gyro_bias, m.acc_bias};
  const double t0 = 0.3, t1 = 1.3;
  const Deltas ref = rk4_reference(m, t0, t1, bias);

  // The RK4 reference agrees with the analytic relative motion (so it is a valid yardstick).
  const NavState si = m.state(t0), sj = m.state(t1);
  const double dt = t1 - t0;
  EXPECT_LT((ref.R.inverse() * (si.R.inverse() * sj.R)).log().norm(), 1e-10);
  EXPECT_LT((ref.v - si.R.inverse() * (sj.v - si.v - m.gravity * dt)).norm(), 1e-10);
  EXPECT_LT((ref.p - si.R.inverse() * (sj.p - si.p - si.v * dt - 0.5 * m.gravity * dt * dt)).norm(),
            1e-10);

  const Preintegration pre = preintegrate(m, t0, t1, 200.0, bias);
  EXPECT_EQ(pre.steps(), 200u);
  EXPECT_NEAR(pre.dt(), dt, 1e-12);
  const Errors e = errors(pre, ref);
  std::printf("200 Hz pre-integration error over 1 s: R %.3e rad, v %.3e m/s, p %.3e m\n", e.R, e.v,
              e.p);
  EXPECT_LT(e.R, 1e-6);
  EXPECT_LT(e.v, 1e-5);
  EXPECT_LT(e.p, 5e-6);
}

TEST(Preintegration, ErrorIsSecondOrderInTheSamplePeriod) {
  Motion m;
  const double t0 = 0.0, t1 = 2.0;
  const Deltas ref = rk4_reference(m, t0, t1, {});
  const Errors e100 = errors(preintegrate(m, t0, t1, 100.0), ref);
  const Errors e200 = errors(preintegrate(m, t0, t1, 200.0), ref);
  // Halving the step must cut the error about four times (first order would give two).
  EXPECT_GT(e100.R / e200.R, 3.5);
  EXPECT_GT(e100.v / e200.v, 3.5);
  EXPECT_GT(e100.p / e200.p, 3.5);
}

TEST(Preintegration, IntegratesExactlyBetweenFrameStampsOffTheSampleGrid) {
  Motion m;
  const double t0 = 0.2013, t1 = 0.9377;  // not multiples of 5 ms
  const std::vector<ImuSample> s = m.samples(0.0, 1.5, 200.0);
  Preintegration pre(ImuBias{}, ImuNoise{});
  ASSERT_TRUE(pre.integrate(s, from_seconds(t0), from_seconds(t1)));
  EXPECT_NEAR(pre.dt(), t1 - t0, 1e-9);
  const Errors e = errors(pre, rk4_reference(m, t0, t1, {}, 20000.0));
  EXPECT_LT(e.R, 5e-6);
  EXPECT_LT(e.v, 5e-5);
  EXPECT_LT(e.p, 2e-5);

  // Samples that do not cover the interval are reported, and the result stays finite.
  Preintegration late(ImuBias{}, ImuNoise{});
  EXPECT_FALSE(late.integrate(s, from_seconds(1.0), from_seconds(1.6)));
  EXPECT_NEAR(late.dt(), 0.6, 1e-9);
  EXPECT_TRUE(late.delta_v().allFinite());
}

TEST(Preintegration, PredictReproducesTheTrajectory) {
  Motion m;
  const double t0 = 0.5, t1 = 1.5;
  const Preintegration pre = preintegrate(m, t0, t1, 200.0);
  const NavState j = pre.predict(m.state(t0), m.gravity);
  const NavState truth = m.state(t1);
  EXPECT_LT((j.R.inverse() * truth.R).log().norm(), 2e-6);
  EXPECT_LT((j.v - truth.v).norm(), 2e-5);
  EXPECT_LT((j.p - truth.p).norm(), 1e-5);
}

// d(delta)/d(bias) by central differences of full re-integrations.
TEST(Preintegration, BiasJacobiansMatchNumericDifferences) {
  Motion m;
  const ImuBias b0{Vec3(0.02, -0.01, 0.03), Vec3(0.1, -0.2, 0.05)};
  Preintegration pre = preintegrate(m, 0.1, 1.1, 200.0, b0);
  const Preintegration base = pre;
  const double eps = 1e-5;
  Mat3 nR, nv_g, nv_a, np_g, np_a;
  for (int k = 0; k < 3; ++k) {
    for (int which = 0; which < 2; ++which) {
      ImuBias plus = b0, minus = b0;
      Vec3& bp = which == 0 ? plus.gyro : plus.acc;
      Vec3& bm = which == 0 ? minus.gyro : minus.acc;
      bp(k) += eps;
      bm(k) -= eps;
      Preintegration pp = base, pm = base;
      pp.reintegrate(plus);
      pm.reintegrate(minus);
      const Vec3 dv = (pp.delta_v() - pm.delta_v()) / (2 * eps);
      const Vec3 dp = (pp.delta_p() - pm.delta_p()) / (2 * eps);
      if (which == 0) {
        nR.col(k) = ((base.delta_R().inverse() * pp.delta_R()).log() -
                     (base.delta_R().inverse() * pm.delta_R()).log()) /
                    (2 * eps);
        nv_g.col(k) = dv;
        np_g.col(k) = dp;
      } else {
        EXPECT_LT((base.delta_R().inverse() * pp.delta_R()).log().norm(), 1e-12);
        nv_a.col(k) = dv;
        np_a.col(k) = dp;
      }
    }
  }
  auto rel = [](const Mat3& a, const Mat3& n) { return (a - n).norm() / std::max(1e-9, n.norm()); };
  EXPECT_LT(rel(pre.dR_dbg(), nR), 1e-6) << pre.dR_dbg() << "\n" << nR;
  EXPECT_LT(rel(pre.dv_dbg(), nv_g), 1e-6) << pre.dv_dbg() << "\n" << nv_g;
  EXPECT_LT(rel(pre.dv_dba(), nv_a), 1e-6);
  EXPECT_LT(rel(pre.dp_dbg(), np_g), 1e-6) << pre.dp_dbg() << "\n" << np_g;
  EXPECT_LT(rel(pre.dp_dba(), np_a), 1e-6);
}

// The first-order correction must beat leaving the deltas at the old bias by far, and its
// error must shrink quadratically with the bias change.
TEST(Preintegration, FirstOrderBiasCorrection) {
  Motion m;
  const ImuBias b0;
  const Preintegration pre = preintegrate(m, 0.0, 1.0, 200.0, b0);
  const Vec3 dg_dir(0.6, -0.3, 0.74), da_dir(-0.5, 0.8, 0.33);
  double prev_err = 0.0;
  for (double step : {4e-3, 2e-3}) {
    ImuBias b1{step * dg_dir, 10.0 * step * da_dir};
    Preintegration exact = pre;
    exact.reintegrate(b1);
    const double errR = (pre.corrected_delta_R(b1.gyro).inverse() * exact.delta_R()).log().norm();
    const double errv = (pre.corrected_delta_v(b1.gyro, b1.acc) - exact.delta_v()).norm();
    const double errp = (pre.corrected_delta_p(b1.gyro, b1.acc) - exact.delta_p()).norm();
    const double uncorrected_v = (pre.delta_v() - exact.delta_v()).norm();
    const double uncorrected_R = (pre.delta_R().inverse() * exact.delta_R()).log().norm();
    EXPECT_LT(errv, 1e-2 * uncorrected_v);
    EXPECT_LT(errR, 1e-2 * uncorrected_R);
    EXPECT_LT(errp, 1e-2 * (pre.delta_p() - exact.delta_p()).norm());
    if (prev_err > 0.0) {
      EXPECT_NEAR(prev_err / errv, 4.0, 0.5);
    }
    prev_err = errv;
  }
}

// Monte-Carlo: 400 noisy runs against the propagated covariance, per 3x3 block of the diagonal.
TEST(Preintegration, CovarianceMatchesMonteCarlo) {
  Motion m;
  ImuNoise noise;
  noise.gyro_noise = 2e-3;
  noise.acc_noise = 2e-2;
  const double rate = 200.0, t0 = 0.0, t1 = 1.0;
  const std::vector<ImuSample> clean = m.samples(t0, t1, rate);
  Preintegration nominal(ImuBias{}, noise);
  nominal.integrate(clean, from_seconds(t0), from_seconds(t1));

  std::mt19937 rng(42);
  const int runs = 400;
  Mat9 sample_cov = Mat9::Zero();
  for (int r = 0; r < runs; ++r) {
    std::vector<ImuSample> noisy = clean;
    test::add_noise(noisy, noise, 1.0 / rate, rng);
    Preintegration pre(ImuBias{}, noise);
    pre.integrate(noisy, from_seconds(t0), from_seconds(t1));
    Vec9 e;
    e << (nominal.delta_R().inverse() * pre.delta_R()).log(), pre.delta_v() - nominal.delta_v(),
        pre.delta_p() - nominal.delta_p();
    sample_cov += e * e.transpose();
  }
  sample_cov /= runs;
  const Mat9& P = nominal.covariance();
  for (int b = 0; b < 3; ++b) {
    const double model = P.block<3, 3>(3 * b, 3 * b).trace();
    const double mc = sample_cov.block<3, 3>(3 * b, 3 * b).trace();
    std::printf("block %d: trace model %.4e  Monte-Carlo %.4e  ratio %.3f\n", b, model, mc,
                mc / model);
    EXPECT_NEAR(mc / model, 1.0, 0.2);
  }
  // Off-diagonal coupling (rotation error drives velocity error): the correlation sign and
  // rough size must agree too.
  const double model_rv = P.block<3, 3>(3, 0).norm();
  EXPECT_LT((sample_cov.block<3, 3>(3, 0) - P.block<3, 3>(3, 0)).norm(), 0.3 * model_rv + 1e-12);
  EXPECT_TRUE(P.allFinite());
  EXPECT_LT((P - P.transpose()).norm(), 1e-12 * P.norm());
}

TEST(Preintegration, SkipsBadStepsAndStaysFinite) {
  Preintegration pre(ImuBias{}, ImuNoise{});
  ImuSample a, b;
  a.t = 0;
  b.t = 0;
  pre.integrate(a, b);  // zero duration
  b.t = 5'000'000;
  b.gyro.x() = std::numeric_limits<double>::quiet_NaN();
  pre.integrate(a, b);
  EXPECT_EQ(pre.skipped_steps(), 2u);
  EXPECT_EQ(pre.steps(), 0u);
  b.gyro.setZero();
  b.acc = Vec3(0, 0, 9.81);
  a.acc = b.acc;
  pre.integrate(a, b);  // still, tiny angles
  EXPECT_EQ(pre.steps(), 1u);
  EXPECT_TRUE(pre.covariance().allFinite());
  EXPECT_TRUE(pre.dR_dbg().allFinite());
  EXPECT_NEAR(pre.delta_v().z(), 9.81 * 0.005, 1e-12);
}

}  // namespace
}  // namespace kestrel::imu
