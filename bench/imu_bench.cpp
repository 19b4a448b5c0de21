// Pre-integration and IMU-factor costs: what one frame interval and one optimizer
// evaluation pay on this machine.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "imu/imu_factor.hpp"
#include "imu/preintegration.hpp"

namespace {

using namespace kestrel;
using namespace kestrel::imu;

std::vector<ImuSample> samples(int n) {
  std::vector<ImuSample> out(n);
  for (int k = 0; k < n; ++k) {
    const double t = k * 0.005;
    out[k].t = static_cast<Timestamp>(k) * 5'000'000;
    out[k].gyro = Vec3(0.3 * std::cos(1.1 * t), 0.2 * std::sin(0.7 * t), 0.5 * std::cos(t));
    out[k].acc = Vec3(0.5 * std::sin(t), -0.3 * std::cos(0.6 * t), 9.81 + 0.2 * std::sin(2 * t));
  }
  return out;
}

void BM_Preintegrate1000(benchmark::State& state) {
  const std::vector<ImuSample> s = samples(1001);
  for (auto _ : state) {
    Preintegration pre(ImuBias{}, ImuNoise{});
    for (std::size_t k = 0; k + 1 < s.size(); ++k) pre.integrate(s[k], s[k + 1]);
    benchmark::DoNotOptimize(pre.covariance().data());
  }
  state.SetItemsProcessed(state.iterations() * 1000);
}
BENCHMARK(BM_Preintegrate1000)->Unit(benchmark::kMicrosecond);

void BM_ImuFactorEvaluate(benchmark::State& state) {
  const std::vector<ImuSample> s = samples(21);
  Preintegration pre(ImuBias{}, ImuNoise{});
  for (std::size_t k = 0; k + 1 < s.size(); ++k) pre.integrate(s[k], s[k + 1]);
  const ImuFactor factor(pre);
  double pose_i[7], pose_j[7];
  pose_to_params(SE3(SO3::exp(Vec3(0.1, 0.2, 0.3)), Vec3(1, 2, 3)), pose_i);
  pose_to_params(SE3(SO3::exp(Vec3(0.12, 0.25, 0.31)), Vec3(1.1, 2.05, 3.0)), pose_j);
  double vi[3] = {0.1, 0.2, 0.0}, vj[3] = {0.15, 0.2, -0.05}, bg[3] = {0.01, 0, 0},
         ba[3] = {0, 0.05, 0};
  const double* params[6] = {pose_i, vi, bg, ba, pose_j, vj};
  double residuals[9];
  double J0[63], J1[27], J2[27], J3[27], J4[63], J5[27];
  double* jac[6] = {J0, J1, J2, J3, J4, J5};
  for (auto _ : state) {
    factor.Evaluate(params, residuals, jac);
    benchmark::DoNotOptimize(residuals);
    benchmark::DoNotOptimize(J4);
  }
}
BENCHMARK(BM_ImuFactorEvaluate)->Unit(benchmark::kNanosecond);

}  // namespace
