#pragma once
// The areas of `kestrel bench` beyond accuracy and speed on the rendered scenes: each runs its
// measurement through the library that owns it, prints one markdown table and returns its
// figures as JSON. `tiny` shrinks the inputs so a test can run every area in seconds.
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace kestrel::bench {

struct AreaOptions {
  bool quick = false;
  bool tiny = false;
  std::string shared_data;  // ../shared/data (sim::default_assets_dir())
  std::string work_dir;     // where rendered scenes go (kept); empty: a temporary folder
};

// evo's stored KITTI 00 results and the TUM tool's DynaSLAM ATE, recomputed by eval/.
nlohmann::json bench_evaluation(const AreaOptions& options);
// Pre-integration against a fine integration of the same samples; static initialization on
// EuRoC V1_01_micro against its ground truth.
nlohmann::json bench_imu(const AreaOptions& options);
// Object database and maps per scenario against the world (pipeline/sim_object_run).
nlohmann::json bench_objects(const AreaOptions& options);
// Telemetry bytes per second per agent on the wire, from a scene's poses and objects.
nlohmann::json bench_telemetry(const AreaOptions& options);
// Dynamic-feature removal of the filter alone per detector and mode on cafe, market and
// uav-zigzag against the mover masks (pipeline/dynamic_evaluation), with the error reasons.
nlohmann::json bench_dynamic(const AreaOptions& options);
// H.264 encode ms per frame and bitrate at 640x480 and 1280x720 on rendered frames.
nlohmann::json bench_video(const AreaOptions& options);

// The live system on market for ten minutes (--quick: 30 s) at real-time pace: frame-to-pose
// latency percentiles, resident memory along the run, map size.
nlohmann::json bench_endurance(const AreaOptions& options);

// Median of a sample (0 for none).
double median_of(std::vector<double> v);

}  // namespace kestrel::bench
