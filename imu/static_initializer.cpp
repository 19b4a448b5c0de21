// Static initialization (imu_initializer.hpp, part a).
#include <cmath>
#include <utility>
#include <vector>

#include "imu/imu_initializer.hpp"

namespace kestrel::imu {
namespace {

struct Moments {
  Vec3 gyro_mean = Vec3::Zero();
  Vec3 acc_mean = Vec3::Zero();
  double gyro_std = 0.0;  // sqrt of the summed per-axis variances of the block means
  double acc_std = 0.0;
  std::size_t blocks = 0;
  bool finite = true;
};

// Means and spread of the samples. The spread is taken over consecutive block means of
// `block` duration: a multirotor's spinning props shake the IMU by 1 m/s^2 and more while it
// sits still, but that vibration is zero-mean at high frequency, and real motion is not.
Moments moments(std::span<const ImuSample> s, Timestamp block) {
  Moments m;
  if (s.empty()) return m;
  std::vector<std::pair<Vec3, Vec3>> means;
  Vec3 g_sum = Vec3::Zero(), a_sum = Vec3::Zero();
  std::size_t n = 0;
  Timestamp block_start = s.front().t;
  for (const ImuSample& x : s) {
    m.finite = m.finite && x.gyro.allFinite() && x.acc.allFinite();
    m.gyro_mean += x.gyro;
    m.acc_mean += x.acc;
    g_sum += x.gyro;
    a_sum += x.acc;
    ++n;
    if (x.t - block_start >= block) {
      means.emplace_back(g_sum / static_cast<double>(n), a_sum / static_cast<double>(n));
      g_sum.setZero();
      a_sum.setZero();
      n = 0;
      block_start = x.t;
    }
  }
  m.gyro_mean /= static_cast<double>(s.size());
  m.acc_mean /= static_cast<double>(s.size());
  m.blocks = means.size();
  if (means.size() < 2) return m;
  Vec3 g_mean = Vec3::Zero(), a_mean = Vec3::Zero();
  for (const auto& [g, a] : means) {
    g_mean += g;
    a_mean += a;
  }
  g_mean /= static_cast<double>(means.size());
  a_mean /= static_cast<double>(means.size());
  Vec3 g2 = Vec3::Zero(), a2 = Vec3::Zero();
  for (const auto& [g, a] : means) {
    g2 += (g - g_mean).cwiseAbs2();
    a2 += (a - a_mean).cwiseAbs2();
  }
  m.gyro_std = std::sqrt(g2.sum() / static_cast<double>(means.size()));
  m.acc_std = std::sqrt(a2.sum() / static_cast<double>(means.size()));
  return m;
}

}  // namespace

const char* to_string(StaticInitStatus status) {
  switch (status) {
    case StaticInitStatus::kOk:
      return "ok";
    case StaticInitStatus::kTooFewSamples:
      return "too few samples";
    case StaticInitStatus::kNotStill:
      return "no still period";
    case StaticInitStatus::kBadGravityMagnitude:
      return "accelerometer magnitude is not gravity";
  }
  return "unknown";
}

SO3 gravity_aligned_rotation(const Vec3& up_in_body) {
  const Vec3 f = up_in_body.normalized();
  // R_w_b = Ry(pitch) Rx(roll), so that R_w_bᵀ e_z = f.
  const double roll = std::atan2(f.y(), f.z());
  const double pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
  return SO3::exp(Vec3(0.0, pitch, 0.0)) * SO3::exp(Vec3(roll, 0.0, 0.0));
}

StaticInitResult static_initialize(std::span<const ImuSample> samples,
                                   const StaticInitOptions& options) {
  StaticInitResult result;
  if (samples.size() < 2) return result;
  const Timestamp window = from_seconds(options.window_s);
  const Timestamp min_still = from_seconds(options.min_still_s);
  if (samples.back().t - samples.front().t < min_still || window <= 0) return result;

  const Timestamp block = from_seconds(options.smoothing_s);
  auto window_still = [&](std::size_t begin, std::size_t end) {
    const Moments m = moments(samples.subspan(begin, end - begin), block);
    return m.finite && m.blocks >= 2 && m.gyro_std <= options.max_gyro_std &&
           m.acc_std <= options.max_acc_std;
  };

  // Consecutive windows; the first run of still windows long enough is the still period.
  // A tail shorter than half a window is not judged and ends any run.
  std::size_t run_begin = 0, run_end = 0;
  bool in_run = false, found = false;
  for (std::size_t begin = 0; begin < samples.size();) {
    std::size_t end = begin;
    while (end < samples.size() && samples[end].t - samples[begin].t < window) ++end;
    const bool short_tail =
        end == samples.size() && samples.back().t - samples[begin].t < window / 2;
    const bool still = !short_tail && window_still(begin, end);
    if (still) {
      if (!in_run) run_begin = begin;
      in_run = true;
      run_end = end;
    }
    if (in_run && (!still || end == samples.size())) {
      if (samples[run_end - 1].t - samples[run_begin].t >= min_still - window / 10) {
        found = true;
        break;
      }
      in_run = false;
    }
    begin = end;
  }
  if (!found) {
    result.status = StaticInitStatus::kNotStill;
    return result;
  }

  const auto still = samples.subspan(run_begin, run_end - run_begin);
  const Moments m = moments(still, block);
  result.still_begin = still.front().t;
  result.still_end = still.back().t;
  result.samples_used = still.size();
  result.gyro_bias = m.gyro_mean;
  result.acc_mean = m.acc_mean;
  result.acc_norm = m.acc_mean.norm();
  result.gyro_std = m.gyro_std;
  result.acc_std = m.acc_std;
  if (!(std::abs(result.acc_norm - options.gravity_magnitude) <= options.gravity_tolerance)) {
    result.status = StaticInitStatus::kBadGravityMagnitude;
    return result;
  }
  result.R_w_b = gravity_aligned_rotation(m.acc_mean);
  result.status = StaticInitStatus::kOk;
  return result;
}

}  // namespace kestrel::imu
