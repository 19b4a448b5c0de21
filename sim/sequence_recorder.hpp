#pragma once
// Writes a whole simulated run as a Kestrel sequence (io/kestrel_sequence.hpp): frames, masks,
// IMU, ground truth, boxes, static objects and the exact scenario parameters.
#include <functional>
#include <string>

#include "sim/simulator.hpp"

namespace kestrel::sim {

struct RecordStats {
  int frames = 0;   // rendered
  int written = 0;  // written (not dropped)
  int imu_samples = 0;
  double render_seconds = 0.0;         // time spent rendering (not writing)
  int frames_with_quarter_movers = 0;  // frames where movers cover >= 25 % of the image
};

// What a recorded folder holds, for caches of renders to tell an old one: raised whenever
// record_sequence writes something new (2: calib.yaml carries the sensor's depth_max).
constexpr int kSequenceLayout = 2;

// progress(done, total) is called after each frame.
RecordStats record_sequence(Simulator& sim, const std::string& dir,
                            const std::function<void(int, int)>& progress = {});

}  // namespace kestrel::sim
