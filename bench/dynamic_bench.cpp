// Dynamic-feature removal of the filter alone, frame pair by frame pair, on simulated scenes with
// ground-truth mover masks: removed / kept percentages per detector mode, and which filter
// reasons the errors come from. Not a timing-critical benchmark: it also prints the filter's
// median time per frame. Usage: bench_dynamic [scenario ...] [--duration S]
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "detect/dynamic_classes.hpp"
#include "detect/yolo_fastest.hpp"
#include "dynamic/dynamic_filter.hpp"
#include "dynamic/removal_metrics.hpp"
#include "io/cv_image.hpp"
#include "pipeline/stage_stats.hpp"
#include "sim/simulator.hpp"
#include "tracking/feature_extractor.hpp"

using namespace kestrel;

namespace {

struct Mode {
  const char* name;
  const char* boxes;  // yolo | truth | none
  dynamic::FilterMode filter;
};

Image gray_of(const Image& color) {
  cv::Mat g;
  cv::cvtColor(io::as_mat(color), g, cv::COLOR_BGR2GRAY);
  return io::to_image(g);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> scenarios;
  double duration = 6.0;
  std::size_t gap = 1;  // frames between the two compared frames
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--duration") && i + 1 < argc) {
      duration = std::stod(argv[++i]);
    } else if (!std::strcmp(argv[i], "--gap") && i + 1 < argc) {
      gap = std::stoul(argv[++i]);
    } else {
      scenarios.emplace_back(argv[i]);
    }
  }
  if (scenarios.empty()) scenarios = {"cafe", "market", "uav-zigzag"};
  const Mode modes[] = {{"hybrid+yolo", "yolo", dynamic::FilterMode::kHybrid},
                        {"hybrid+truth boxes", "truth", dynamic::FilterMode::kHybrid},
                        {"detection only (yolo)", "yolo", dynamic::FilterMode::kDetectionOnly},
                        {"geometry only", "none", dynamic::FilterMode::kGeometryOnly}};
  detect::YoloFastest yolo(detect::find_models_dir());
  detect::DynamicClassList classes;

  std::printf(
      "| scenario | mode | dynamic removed | static kept | filter ms p50 "
      "|\n|---|---|---|---|---|\n");
  for (const std::string& name : scenarios) {
    sim::ScenarioOverrides over;
    over.duration = duration;
    sim::Simulator sim(sim::load_scenario(name, over));
    const Calibration& calib = sim.calibration();
    tracking::FeatureExtractor extractor(calib.camera);
    std::vector<sim::SimFrame> frames;
    for (int k = 0; k < sim.frame_count(); ++k) frames.push_back(sim.render(k));
    std::vector<std::vector<dynamic::BoxRegion>> yolo_boxes(frames.size()),
        truth_boxes(frames.size());
    for (std::size_t k = 0; k < frames.size(); ++k) {
      for (const auto& d : yolo.detect(frames[k].color, frames[k].stamp).boxes) {
        if (classes.is_dynamic_class(d.label))
          yolo_boxes[k].push_back({d.x_min, d.y_min, d.x_max, d.y_max});
      }
      for (const auto& b : frames[k].boxes) {
        if (b.instance < 1000) {
          truth_boxes[k].push_back(
              {float(b.x_min), float(b.y_min), float(b.x_max), float(b.y_max)});
        }
      }
    }
    for (const Mode& mode : modes) {
      dynamic::RemovalCounts total;
      std::size_t on_moving = 0, on_still = 0, moving_removed = 0;
      std::vector<double> ms;
      dynamic::DynamicFilterOptions opt;
      opt.mode = mode.filter;
      for (std::size_t k = gap; k < frames.size(); ++k) {
        const auto features =
            extractor.extract(frames[k].color, nullptr, &frames[k].depth, calib.depth_scale);
        const Image prev = gray_of(frames[k - gap].color), cur = gray_of(frames[k].color);
        dynamic::DynamicFilterInput in;
        in.prev_gray = &prev;
        in.cur_gray = &cur;
        for (const auto& kp : features.keypoints) in.points.push_back(kp.px);
        in.depth_m = features.depth;
        in.K = calib.camera.K();
        const SE3 T_w_c0 = frames[k - gap].body.T_w_b * calib.T_body_camera;
        const SE3 T_w_c1 = frames[k].body.T_w_b * calib.T_body_camera;
        in.R_cur_prev = (T_w_c1.inverse() * T_w_c0).rotation();  // a perfect gyro
        if (!std::strcmp(mode.boxes, "yolo")) in.boxes = yolo_boxes[k];
        if (!std::strcmp(mode.boxes, "truth")) in.boxes = truth_boxes[k];
        const auto t0 = std::chrono::steady_clock::now();
        const auto r = dynamic::classify_features(in, opt);
        ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
        total += dynamic::count_removal(in.points, r.labels, frames[k].mask, &r.reasons);
        for (std::size_t i = 0; i < in.points.size(); ++i) {
          const int u = int(in.points[i].x()), v = int(in.points[i].y());
          const int id = frames[k].mask.row<std::uint16_t>(v)[u];
          if (!id) continue;
          bool moving = false;
          for (const auto& b : frames[k].boxes) moving |= b.instance == id && b.moving;
          (moving ? on_moving : on_still) += 1;
          if (moving && r.labels[i] == dynamic::FeatureLabel::kDynamic) ++moving_removed;
        }
      }
      std::printf("| %s | %s | %.1f%% | %.1f%% | %.2f |\n", name.c_str(), mode.name,
                  total.removed_percent(), total.kept_percent(), pipeline::percentile(ms, 50));
      std::printf("|   |   missed by reason:");
      for (std::size_t i = 0; i < total.kReasons; ++i) {
        if (total.dynamic_missed_by_reason[i]) {
          std::printf(" %s %zu", dynamic::to_string(static_cast<dynamic::LabelReason>(i)),
                      total.dynamic_missed_by_reason[i]);
        }
      }
      std::printf(" / static removed by:");
      for (std::size_t i = 0; i < total.kReasons; ++i) {
        if (total.static_removed_by_reason[i]) {
          std::printf(" %s %zu", dynamic::to_string(static_cast<dynamic::LabelReason>(i)),
                      total.static_removed_by_reason[i]);
        }
      }
      std::printf(
          " | movers: %zu features on moving ones (%.1f%% removed), %zu on still ones | |\n",
          on_moving, 100.0 * moving_removed / std::max<std::size_t>(on_moving, 1), on_still);
      std::fflush(stdout);
    }
  }
  return 0;
}
