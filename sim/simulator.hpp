#pragma once
// Renders a scenario frame by frame: colour, depth, mover masks, ground-truth boxes, and the
// IMU stream, all from one analytic trajectory. Every output is a pure function of the
// scenario (seed included) and the frame index, so runs are byte-for-byte repeatable.
#include <memory>
#include <string>
#include <vector>

#include "core/calibration.hpp"
#include "core/image.hpp"
#include "core/imu.hpp"
#include "sim/rasterizer.hpp"
#include "sim/scenario.hpp"
#include "sim/sensor_model.hpp"
#include "sim/spline_trajectory.hpp"
#include "sim/world.hpp"

namespace kestrel::sim {

struct SimBox {
  int instance = 0;  // mover id (1..) or static object id (kFirstObjectId..)
  std::string label;
  int x_min = 0, y_min = 0, x_max = 0, y_max = 0;  // pixels, max exclusive
  bool moving = false;
  double occluded = 0.0;  // fraction of the instance's in-image pixels hidden by others
  int pixels = 0;         // visible pixels
};

struct SimFrame {
  int index = 0;
  double time = 0.0;     // true exposure time, seconds from the start
  Timestamp stamp = 0;   // what the sensor reports (jitter included)
  bool dropped = false;  // the sensor lost this frame (only the truth exists)
  BodyState body;        // truth at `time`
  Image color;           // BGR 8-bit
  Image depth;           // 16-bit, calib.depth_scale per metre
  Image mask;            // 16-bit mover ids, 0 = static
  std::vector<SimBox> boxes;
  double mover_fraction = 0.0;  // share of the image covered by movers
};

class Simulator {
 public:
  explicit Simulator(Scenario scenario);

  int frame_count() const { return frame_count_; }
  double duration() const { return duration_; }
  const Scenario& scenario() const { return scenario_; }
  const Calibration& calibration() const { return scenario_.calib; }
  const SplineTrajectory& trajectory() const { return *trajectory_; }
  const World& world() const { return *world_; }

  double frame_time(int k) const;
  // When frame k is exposed, the stamp its sensor reports and whether the sensor drops it: what
  // render(k) says about time, without drawing anything.
  struct FrameTiming {
    double time = 0.0;
    Timestamp stamp = 0;
    bool dropped = false;
  };
  FrameTiming frame_timing(int k) const;
  SE3 camera_pose(double t) const;  // T_w_c
  // Frame k; pixel buffers are rendered even for dropped frames (they are simply not written).
  SimFrame render(int k);
  // The whole IMU stream from t = 0 to the end, at calib.imu.rate_hz.
  std::vector<ImuSample> imu() const;

 private:
  void draw_scene(double t, RenderTarget& target, std::vector<bool>& moving);

  Scenario scenario_;
  std::unique_ptr<World> world_;
  std::unique_ptr<SplineTrajectory> trajectory_;
  SensorModel sensor_;
  Rasterizer rasterizer_;
  RenderTarget target_;
  RenderTarget blur_target_;
  std::vector<std::uint16_t> blur_sum_;
  Mesh mover_mesh_;
  double duration_ = 0.0;
  int frame_count_ = 0;
};

// Body trajectory of a scenario (waypoints repeated `laps` times, wobble from the seed).
SplineTrajectory make_trajectory(const Scenario& scenario);

}  // namespace kestrel::sim
