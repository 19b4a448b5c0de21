#pragma once
// The run report (issue 9): one self-contained report.html per run — trajectories against
// ground truth, APE along time, the dynamic-removal table, per-stage timing, a strip of frames,
// the occupancy grid when there is one, and the command, config and version that produced it.
// Everything is inline (SVG, base64 PNG): the file opens with no network access.
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/image.hpp"
#include "core/trajectory.hpp"

namespace kestrel::report {

struct StageTiming {
  std::string stage;
  std::size_t count = 0;
  double p50_ms = 0, p90_ms = 0, max_ms = 0;
};

// One run of the system; the demo's report compares two of them.
struct RunRecord {
  std::string name;         // e.g. "hybrid", "off"
  std::string description;  // e.g. "detector yolo, dynamic rejection hybrid"
  Trajectory estimate;      // T_w_body
  std::size_t frames = 0, tracked = 0, lost = 0;
  bool has_removal = false;  // dynamic-removal counts need truth masks
  std::size_t dynamic_total = 0, dynamic_removed = 0, static_total = 0, static_kept = 0;
  double tracking_ms_median = 0, detector_ms_median = 0, wall_seconds = 0;
  std::vector<StageTiming> stages;
  std::map<std::string, std::size_t> counters;
  // Resident memory along the run: (seconds of the stream, MiB); empty when not sampled.
  std::vector<std::pair<double, double>> memory_mib;
};

struct FrameBox {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // pixels
  std::string label;
  bool moving = false;
};

struct FramePoint {
  double x = 0, y = 0;  // pixels
  bool dynamic = false;
};

// One image of the strip, with what is drawn over it (as SVG, so the pixels stay untouched).
struct StripFrame {
  std::string caption;
  Image image;  // 8-bit grey or BGR
  std::vector<FrameBox> boxes;
  std::vector<FramePoint> points;
};

// A 2D occupancy grid (ROS map_server convention: row 0 is the top, origin is the world
// position of the bottom-left cell), with objects and planned paths on it.
struct GridMap {
  Image occupancy;           // 8-bit grey: 0 occupied, 254 free, 205 unknown
  double resolution = 0.05;  // metres per cell
  double origin_x = 0, origin_y = 0;
  struct Object {
    std::string label;
    double x = 0, y = 0;
  };
  std::vector<Object> objects;
  std::vector<std::vector<std::pair<double, double>>> paths;  // world x, y
};

struct ReportInput {
  std::string title = "Kestrel run report";
  std::string command_line;
  std::string config_text;  // the YAML (or the flags) the run used
  std::string version;      // KESTREL_VERSION
  std::string dataset;      // what was run
  std::optional<Trajectory> ground_truth;
  std::vector<RunRecord> runs;
  std::vector<StripFrame> frames;
  std::optional<GridMap> grid;
  std::vector<std::string> notes;  // free sentences shown under the title
};

// The whole page as text. APE is computed here (SE(3) Umeyama alignment, evo association).
std::string render_report(const ReportInput& input);
// Writes render_report() to path; throws kestrel::Error naming the path when it cannot.
void write_report(const ReportInput& input, const std::string& path);

}  // namespace kestrel::report
