// IMU area. Pre-integration: imu::Preintegration over 0.5 s windows (a keyframe interval) of
// the simulator's uav-zigzag IMU stream, against the same samples integrated with 20 linearly
// interpolated sub-steps each (the midpoint scheme's discretization error is what is left).
// Static initialization: imu::static_initialize on EuRoC V1_01_micro against OpenVINS' ground
// truth (gyro bias, direction of gravity).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>

#include "apps/bench_areas.hpp"
#include "imu/imu_initializer.hpp"
#include "imu/preintegration.hpp"
#include "io/dataset_lists.hpp"
#include "io/text_lines.hpp"
#include "sim/scenario.hpp"
#include "sim/simulator.hpp"

namespace kestrel::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kDeg = 180.0 / std::numbers::pi;

ImuSample lerp(const ImuSample& a, const ImuSample& b, double s) {
  ImuSample m;
  m.t = a.t + static_cast<Timestamp>(std::llround(s * static_cast<double>(b.t - a.t)));
  m.gyro = a.gyro + s * (b.gyro - a.gyro);
  m.acc = a.acc + s * (b.acc - a.acc);
  return m;
}

json preintegration_area(const AreaOptions& o) {
  sim::ScenarioOverrides ov;
  ov.duration = o.tiny ? 2.0 : o.quick ? 10.0 : 30.0;
  const sim::Simulator sim(sim::load_scenario("uav-zigzag", ov));
  const std::vector<ImuSample> imu = sim.imu();
  const double rate = sim.calibration().imu.rate_hz;
  const auto window = static_cast<std::size_t>(std::lround(0.5 * rate));
  constexpr int kSub = 20;
  std::vector<double> rot_deg, vel, pos, ms;
  for (std::size_t i = 0; i + window < imu.size(); i += window) {
    imu::Preintegration coarse(imu::ImuBias{}, ImuNoise{}), fine(imu::ImuBias{}, ImuNoise{});
    const auto t0 = std::chrono::steady_clock::now();
    for (std::size_t k = i; k < i + window; ++k) coarse.integrate(imu[k], imu[k + 1]);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    for (std::size_t k = i; k < i + window; ++k)
      for (int s = 0; s < kSub; ++s)
        fine.integrate(lerp(imu[k], imu[k + 1], double(s) / kSub),
                       lerp(imu[k], imu[k + 1], double(s + 1) / kSub));
    rot_deg.push_back((coarse.delta_R().inverse() * fine.delta_R()).log().norm() * kDeg);
    vel.push_back((coarse.delta_v() - fine.delta_v()).norm());
    pos.push_back((coarse.delta_p() - fine.delta_p()).norm());
  }
  const auto max_of = [](const std::vector<double>& v) {
    return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
  };
  std::printf(
      "| pre-integration vs %dx finer, uav-zigzag, %zu windows of 0.5 s at %.0f Hz | "
      "rotation %.2e / %.2e deg, velocity %.2e / %.2e m/s, position %.2e / %.2e m "
      "(median / max); %.3f ms per window |\n",
      kSub, rot_deg.size(), rate, median_of(rot_deg), max_of(rot_deg), median_of(vel), max_of(vel),
      median_of(pos), max_of(pos), median_of(ms));
  return {{"scenario", "uav-zigzag"},
          {"windows", rot_deg.size()},
          {"window_s", 0.5},
          {"rate_hz", rate},
          {"substeps", kSub},
          {"rotation_error_deg_median", median_of(rot_deg)},
          {"rotation_error_deg_max", max_of(rot_deg)},
          {"velocity_error_mps_median", median_of(vel)},
          {"velocity_error_mps_max", max_of(vel)},
          {"position_error_m_median", median_of(pos)},
          {"position_error_m_max", max_of(pos)},
          {"ms_per_window_median", median_of(ms)}};
}

json static_init_area(const AreaOptions& o) {
  const fs::path dir = fs::path(o.shared_data) / "euroc" / "V1_01_micro";
  const fs::path imu_csv = dir / "mav0" / "imu0" / "data.csv";
  const fs::path gt_csv = dir / "groundtruth_open_vins" / "V1_01_easy.csv";
  if (!fs::exists(imu_csv) || !fs::exists(gt_csv)) {
    std::printf("| static initialization, EuRoC V1_01_micro | %s missing |\n", dir.c_str());
    return {{"status", "missing data"}};
  }
  const std::vector<ImuSample> imu = io::parse_asl_imu_csv(io::TextTable::read(imu_csv.string()));
  const auto t0 = std::chrono::steady_clock::now();
  const imu::StaticInitResult r = imu::static_initialize(imu);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  // Ground truth: the mean gyro bias over the clip (it barely moves while still) and the
  // first pose's up direction in the body frame.
  const io::TextTable table = io::TextTable::read(gt_csv.string());
  Vec3 gt_bg = Vec3::Zero();
  std::optional<SO3> R0;
  for (const io::TextRow& row : table.rows()) {
    table.require_fields(row, 17, "time, p, q (w x y z), v, b_w, b_a");
    gt_bg += Vec3(table.number(row, 11, "bwx"), table.number(row, 12, "bwy"),
                  table.number(row, 13, "bwz"));
    if (!R0) {
      R0 = SO3(Quat(table.number(row, 4, "qw"), table.number(row, 5, "qx"),
                    table.number(row, 6, "qy"), table.number(row, 7, "qz")));
    }
  }
  gt_bg /= std::max<double>(1.0, static_cast<double>(table.rows().size()));
  if (!r.ok() || !R0) {
    std::printf("| static initialization, EuRoC V1_01_micro | failed: %s |\n",
                imu::to_string(r.status));
    return {{"status", imu::to_string(r.status)}};
  }
  const Vec3 up_gt = R0->inverse() * Vec3::UnitZ();
  const Vec3 up_est = r.R_w_b.inverse() * Vec3::UnitZ();
  const double angle = std::acos(std::clamp(up_gt.dot(up_est), -1.0, 1.0)) * kDeg;
  const double bias_err = (r.gyro_bias - gt_bg).norm();
  const double still = to_seconds(r.still_end - r.still_begin);
  std::printf(
      "| static initialization, EuRoC V1_01_micro | still %.2f s, gyro bias error "
      "%.2e rad/s, gravity direction error %.3f deg, |acc| %.4f m/s^2, %.2f ms |\n",
      still, bias_err, angle, r.acc_norm, ms);
  return {{"status", "ok"},
          {"still_s", still},
          {"gyro_bias_error_radps", bias_err},
          {"gravity_angle_error_deg", angle},
          {"acc_norm", r.acc_norm},
          {"ms", ms}};
}

}  // namespace

json bench_imu(const AreaOptions& o) {
  std::printf("\n## IMU\n\n| check | figures |\n|---|---|\n");
  json j;
  j["preintegration"] = preintegration_area(o);
  j["static_init_euroc_v1_01_micro"] = static_init_area(o);
  return j;
}

}  // namespace kestrel::bench
