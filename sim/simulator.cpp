#include "sim/simulator.hpp"

#include <algorithm>
#include <cmath>

#include "sim/imu_synthesizer.hpp"
#include "sim/procedural_texture.hpp"

namespace kestrel::sim {
namespace {

std::uint8_t channel(const std::array<int, 3>& rgb, int bgr_index) {
  return static_cast<std::uint8_t>(rgb[static_cast<std::size_t>(2 - bgr_index)]);
}

}  // namespace

SplineTrajectory make_trajectory(const Scenario& sc) {
  const TrajectorySpec& ts = sc.trajectory;
  std::vector<TrajectoryKnot> knots;
  for (int lap = 0; lap < ts.laps; ++lap)
    knots.insert(knots.end(), ts.knots.begin(), ts.knots.end());
  Wobble wobble;
  // Three incommensurate frequencies per channel read as an unsteady hand or a hovering drone.
  const double ratios[3] = {1.0, 1.73, 2.91};
  std::uint64_t k = 0;
  const auto phase = [&] {
    return 2.0 * M_PI * static_cast<double>(hash_combine(sc.seed, 0x70b + ++k) >> 11) /
           9007199254740992.0;
  };
  for (int c = 0; c < 6; ++c) {
    const bool rot = c >= 3;
    double amp = rot ? ts.wobble_rotation : ts.wobble_position;
    if (ts.kind == "ugv" && (c == 2 || c == 4 || c == 5)) amp = 0.0;  // a ground robot stays level
    if (amp <= 0.0) continue;
    for (int j = 0; j < 3; ++j) {
      wobble.terms.push_back(
          {c, amp / (j + 1), ts.wobble_frequency * ratios[j] * (1.0 + 0.07 * c), phase()});
    }
  }
  wobble.fade_z_still = ts.wobble_fade_still;
  wobble.fade_z_full = ts.wobble_fade_full;
  return SplineTrajectory(knots, ts.segment_time, wobble);
}

Simulator::Simulator(Scenario scenario)
    : scenario_(std::move(scenario)),
      sensor_(scenario_.sensor, scenario_.seed),
      rasterizer_(scenario_.calib.camera) {
  world_ = std::make_unique<World>(scenario_);
  trajectory_ = std::make_unique<SplineTrajectory>(make_trajectory(scenario_));
  duration_ = scenario_.duration > 0 ? scenario_.duration : trajectory_->duration();
  frame_count_ =
      std::max(1, static_cast<int>(std::floor(duration_ * scenario_.calib.fps + 1e-6)) + 1);
  const PinholeCamera& cam = scenario_.calib.camera;
  target_.resize(cam.width, cam.height, kMaxInstances);
  if (scenario_.sensor.motion_blur > 1) blur_target_.resize(cam.width, cam.height, kMaxInstances);
}

double Simulator::frame_time(int k) const { return static_cast<double>(k) / scenario_.calib.fps; }

SE3 Simulator::camera_pose(double t) const {
  return trajectory_->state(t).T_w_b * scenario_.calib.T_body_camera;
}

void Simulator::draw_scene(double t, RenderTarget& target, std::vector<bool>& moving) {
  std::uint8_t top[3], bottom[3];
  for (int c = 0; c < 3; ++c) {
    top[c] = channel(scenario_.sky_top, c);
    bottom[c] = channel(scenario_.sky_bottom, c);
  }
  target.clear(top, bottom);
  const SE3 T_w_c = camera_pose(t);
  const SE3 T_c_w = T_w_c.inverse();
  rasterizer_.draw(world_->static_mesh(), world_->textures(), T_c_w, target);
  world_->mover_mesh(t, T_w_c.translation(), mover_mesh_, moving);
  rasterizer_.draw(mover_mesh_, world_->textures(), T_c_w, target);
}

Simulator::FrameTiming Simulator::frame_timing(int k) const {
  FrameTiming ft;
  ft.time = frame_time(k);
  const SensorSpec& ss = scenario_.sensor;
  double jitter = 0.0;
  if (ss.jitter > 0.0) jitter = ss.jitter * sensor_.gaussian(0x717, static_cast<std::uint64_t>(k));
  ft.stamp = static_cast<Timestamp>(std::llround((ft.time + jitter) * 1e9));
  ft.dropped = k > 0 && ss.drop_rate > 0.0 &&
               sensor_.uniform(0xd50, static_cast<std::uint64_t>(k)) < ss.drop_rate;
  return ft;
}

SimFrame Simulator::render(int k) {
  SimFrame f;
  f.index = k;
  const FrameTiming ft = frame_timing(k);
  f.time = ft.time;
  f.body = trajectory_->state(f.time);
  f.stamp = ft.stamp;
  f.dropped = ft.dropped;
  const SensorSpec& ss = scenario_.sensor;

  std::vector<bool> moving;
  draw_scene(f.time, target_, moving);
  const int W = target_.width, H = target_.height;
  const std::size_t n = static_cast<std::size_t>(W) * H;

  // Colour: the average of sub-frames across the exposure when motion blur is on.
  const double gain = sensor_.exposure_gain(f.time);
  if (ss.motion_blur > 1) {
    blur_sum_.assign(n * 3, 0);
    std::vector<bool> unused;
    for (int j = 0; j < ss.motion_blur; ++j) {
      const double tj = f.time + ss.exposure_time * ((j + 0.5) / ss.motion_blur - 0.5);
      draw_scene(tj, blur_target_, unused);
      for (std::size_t i = 0; i < n * 3; ++i)
        blur_sum_[i] = static_cast<std::uint16_t>(blur_sum_[i] + blur_target_.bgr[i]);
    }
    std::vector<std::uint8_t> avg(n * 3);
    for (std::size_t i = 0; i < n * 3; ++i)
      avg[i] = static_cast<std::uint8_t>((blur_sum_[i] + ss.motion_blur / 2) / ss.motion_blur);
    f.color = sensor_.color(avg, W, H, gain, k);
  } else {
    f.color = sensor_.color(target_.bgr, W, H, gain, k);
  }
  f.depth = sensor_.depth(target_.inv_depth, W, H, scenario_.calib.depth_scale, k);

  // Mask and boxes from the id buffer of the exact instant.
  f.mask = Image::allocate(W, H, 1, PixelType::kU16);
  struct Extent {
    int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1, count = 0;
  };
  std::vector<Extent> ext(kMaxInstances);
  const int n_movers = static_cast<int>(world_->movers().size());
  std::size_t mover_pixels = 0;
  for (int y = 0; y < H; ++y) {
    const std::uint16_t* ids = target_.id.data() + static_cast<std::size_t>(y) * W;
    std::uint16_t* m = f.mask.row<std::uint16_t>(y);
    for (int x = 0; x < W; ++x) {
      const std::uint16_t id = ids[x];
      const bool mover = id >= 1 && id <= n_movers;
      m[x] = mover ? id : 0;
      mover_pixels += mover;
      if (id == 0) continue;
      Extent& e = ext[id];
      e.x0 = std::min(e.x0, x);
      e.y0 = std::min(e.y0, y);
      e.x1 = std::max(e.x1, x);
      e.y1 = std::max(e.y1, y);
      ++e.count;
    }
  }
  f.mover_fraction = static_cast<double>(mover_pixels) / static_cast<double>(n);
  const auto add_box = [&](int id, const std::string& label, bool is_moving) {
    const Extent& e = ext[static_cast<std::size_t>(id)];
    if (e.count == 0) return;
    SimBox b;
    b.instance = id;
    b.label = label;
    b.x_min = e.x0;
    b.y_min = e.y0;
    b.x_max = e.x1 + 1;
    b.y_max = e.y1 + 1;
    b.moving = is_moving;
    b.pixels = e.count;
    const double frags = target_.fragments[static_cast<std::size_t>(id)];
    b.occluded = frags > 0 ? std::clamp(1.0 - e.count / frags, 0.0, 1.0) : 0.0;
    f.boxes.push_back(b);
  };
  for (int i = 0; i < n_movers; ++i)
    add_box(i + 1, world_->movers()[static_cast<std::size_t>(i)].label,
            moving[static_cast<std::size_t>(i)]);
  for (const StaticObject& o : world_->objects()) add_box(o.id, o.label, false);
  return f;
}

std::vector<ImuSample> Simulator::imu() const {
  const ImuNoise& noise = scenario_.calib.imu;
  ImuSynthesizer synth(noise, hash_combine(scenario_.seed, 0x1a0), scenario_.sensor.noise);
  const auto count = static_cast<long long>(std::floor(duration_ * noise.rate_hz + 1e-6)) + 1;
  std::vector<ImuSample> out;
  out.reserve(static_cast<std::size_t>(count));
  for (long long i = 0; i < count; ++i) {
    const double t = static_cast<double>(i) / noise.rate_hz;
    out.push_back(
        synth.sample(trajectory_->state(t), static_cast<Timestamp>(std::llround(t * 1e9))));
  }
  return out;
}

}  // namespace kestrel::sim
