#include "pipeline/dynamic_evaluation.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "core/error.hpp"
#include "core/so3.hpp"
#include "core/thread_cpu_time.hpp"
#include "detect/dynamic_classes.hpp"
#include "imu/inertial_predictor.hpp"
#include "io/cv_image.hpp"
#include "io/dataset.hpp"
#include "io/kestrel_sequence.hpp"
#include "io/trajectory_io.hpp"
#include "pipeline/imu_buffer.hpp"
#include "pipeline/system.hpp"
#include "tracking/feature_extractor.hpp"
#include "tracking/tracker.hpp"

namespace kestrel::pipeline {
namespace {

Image gray_of(const Image& color) {
  if (color.channels == 1) return color;
  cv::Mat g;
  cv::cvtColor(io::as_mat(color), g, cv::COLOR_BGR2GRAY);
  return io::to_image(g);
}

// The ground-truth body pose at each frame stamp (within 1 ms); nothing for a frame it misses.
std::vector<std::optional<SE3>> truth_at_frames(const std::string& path,
                                                const std::vector<Timestamp>& stamps) {
  std::vector<std::optional<SE3>> out(stamps.size());
  if (!std::filesystem::exists(path)) return out;
  const io::PoseSeries gt = io::read_pose_series(path);
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    const double t = stamps[k] * 1e-9;
    const auto it = std::lower_bound(gt.stamps.begin(), gt.stamps.end(), t - 1e-3);
    if (it != gt.stamps.end() && std::fabs(*it - t) <= 1e-3) {
      out[k] = SE3(gt.poses[static_cast<std::size_t>(it - gt.stamps.begin())]);
    }
  }
  return out;
}

}  // namespace

DynamicEvalScene load_dynamic_eval_scene(const std::string& dir,
                                         const std::vector<detect::Detector*>& detectors,
                                         std::size_t max_frames) {
  if (!std::filesystem::is_directory(dir + "/dynamic")) {
    throw Error::at(dir + "/dynamic", 0, "", "no ground-truth mover masks (a Kestrel sequence?)");
  }
  auto source = io::open_dataset("kestrel:" + dir);
  const Calibration& calib = source->calibration();
  // The tracker's own extractor, built from the options the System gives it.
  const tracking::FeatureExtractor extractor(calib.camera, tracking::TrackerOptions{}.features);
  DynamicEvalScene scene;
  scene.dir = dir;
  scene.K = calib.camera.K();
  scene.camera = calib.camera;
  scene.depth_range_m = calib.depth_max.value_or(0.0);
  // All frames and IMU samples first: the gyro rotation of a frame needs the samples after it.
  std::vector<RgbdFrame> frames;
  ImuBuffer imu;
  while (auto m = source->next()) {
    if (const auto* s = std::get_if<ImuSample>(&*m)) {
      imu.add(*s);
    } else if (auto* f = std::get_if<RgbdFrame>(&*m)) {
      if (max_frames == 0 || frames.size() < max_frames) frames.push_back(std::move(*f));
    }
  }
  scene.frames.reserve(frames.size());
  std::vector<Timestamp> stamps;
  for (const RgbdFrame& f : frames) stamps.push_back(f.t);
  const std::vector<std::optional<SE3>> truth = truth_at_frames(dir + "/groundtruth.txt", stamps);
  // The System's IMU predictor, its fixes the true poses (Kestrel worlds are z up, gravity
  // known), so that the filter is handed the translation prior the System hands it.
  imu::InertialPredictorOptions predictor_options;
  predictor_options.noise = calib.imu;
  imu::InertialPredictor predictor(predictor_options);
  const SystemOptions system_options;
  Timestamp imu_fed_until = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const RgbdFrame& f = frames[k];
    DynamicEvalFrame e;
    e.t = f.t;
    e.gray = gray_of(f.color);
    e.mask = io::read_dynamic_mask(dir, f.t);
    e.depth = f.depth;
    e.depth_scale = f.depth_scale;
    const tracking::FrameFeatures ff = extractor.extract(f);
    for (const auto& kp : ff.keypoints) e.points.push_back(kp.px);
    e.depth_m = ff.sensor_depth;
    // The previous frame's stamp from the scene: frames[k - 1] was emptied, stamp too, below.
    if (k > 0 && calib.has_imu) {
      e.R_cur_prev = gyro_rotation(imu, scene.frames[k - 1].t, f.t, calib.T_body_camera);
      if (!imu.empty() && f.t > imu_fed_until) {
        predictor.add_samples(imu.between(std::max(imu_fed_until, imu.earliest()), f.t));
        imu_fed_until = f.t;
      }
      const auto p = predictor.predict(f.t);
      if (e.R_cur_prev && p && truth[k - 1]) {
        const SE3 T_w_c_prev = *truth[k - 1] * calib.T_body_camera;
        const SE3 T_w_c_pred = p->T_w_b * calib.T_body_camera;
        e.t_cur_prev = (T_w_c_pred.inverse() * T_w_c_prev).translation();
        const InertialPriorSigmas sigmas = inertial_prior_sigmas(system_options, p->since_fix_s);
        e.prior_translation_sigma_m = sigmas.translation_m;
        e.prior_rotation_sigma_rad = sigmas.rotation_rad;
      }
    }
    if (calib.has_imu && truth[k]) predictor.add_fix(f.t, *truth[k]);
    for (detect::Detector* d : detectors) e.detections.push_back(d->detect(f.color, f.t));
    scene.frames.push_back(std::move(e));
    frames[k] = RgbdFrame{};  // the colour and depth images are no longer needed
  }
  return scene;
}

DynamicEvalResult evaluate_dynamic_filter(const DynamicEvalScene& scene,
                                          const DynamicEvalOptions& options) {
  const detect::DynamicClassList classes = options.dynamic_classes.empty()
                                               ? detect::DynamicClassList()
                                               : detect::DynamicClassList(options.dynamic_classes);
  const detect::DynamicClassList parkable =
      options.parkable_classes.empty()
          ? detect::DynamicClassList(detect::default_parkable_classes())
          : detect::DynamicClassList(options.parkable_classes);
  dynamic::ParkedBoxTracker parked(options.parked);
  detect::BoxCoaster coaster(options.box_coasting);
  DynamicEvalResult out;
  const tracking::FeatureExtractor extractor(scene.camera, tracking::TrackerOptions{}.features);
  std::vector<dynamic::BoxRegion> last_boxes;  // the last frame's, as the System keeps them
  // The last judged frame's pyramid, the next one's previous (as the System keeps it); the
  // filter checks it was built from the image it is given as previous and rebuilds otherwise.
  dynamic::FlowPyramid last_pyramid;
  dynamic::ResidualTrail last_trail;  // the last judged frame's, as the System keeps it
  for (std::size_t k = 0; k < scene.frames.size(); ++k) {
    const DynamicEvalFrame& f = scene.frames[k];
    dynamic::DynamicFilterInput in;
    in.cur_gray = &f.gray;
    in.points = f.points;
    in.depth_m = f.depth_m;
    // The last boxes are the previous frame's: none on the first.
    const LastMoverMasks m =
        k == 0 ? LastMoverMasks{}
               : last_mover_masks(last_boxes, scene.frames[k - 1].depth,
                                  scene.frames[k - 1].depth_scale, f.gray.width, f.gray.height,
                                  options.mover_budget_margin_px, options.mover_silhouettes,
                                  options.mover_silhouette, options.filter);
    if (m.any()) {
      const tracking::FrameFeatures ff =
          extractor.extract(f.gray, m.silhouette.empty() ? nullptr : &m.silhouette,
                            f.depth.empty() ? nullptr : &f.depth, f.depth_scale, f.t,
                            m.movers.empty() ? nullptr : &m.movers);
      in.points.clear();
      for (const auto& kp : ff.keypoints) in.points.push_back(kp.px);
      in.depth_m = ff.sensor_depth;
    }
    if (!f.depth.empty()) in.cur_depth = &f.depth;
    in.depth_scale = f.depth_scale;
    in.K = scene.K;
    in.depth_range_m = scene.depth_range_m;
    // Frame k against frame k - gap: the older image, its depth, the gyro rotation chained.
    const auto set_prev = [&](dynamic::DynamicFilterInput& x, int gap) {
      const std::size_t prev = k - std::min<std::size_t>(k, static_cast<std::size_t>(gap));
      x.prev_gray = &scene.frames[prev].gray;
      x.R_cur_prev = f.R_cur_prev;
      x.t_cur_prev.reset();
      if (gap == 1 && options.motion_prior && f.t_cur_prev && f.R_cur_prev) {
        x.t_cur_prev = f.t_cur_prev;
        x.prior_translation_sigma_m = f.prior_translation_sigma_m;
        x.prior_rotation_sigma_rad = f.prior_rotation_sigma_rad;
      }
      for (std::size_t j = k - 1; j > prev && x.R_cur_prev; --j) {
        if (!scene.frames[j].R_cur_prev) {
          x.R_cur_prev.reset();
          break;
        }
        x.R_cur_prev = *x.R_cur_prev * *scene.frames[j].R_cur_prev;
      }
      x.prev_depth = nullptr;
      if (options.prev_depth && !scene.frames[prev].depth.empty()) {
        x.prev_depth = &scene.frames[prev].depth;
        x.depth_scale = scene.frames[prev].depth_scale;
      }
    };
    if (options.detector >= 0) {
      if (static_cast<std::size_t>(options.detector) >= f.detections.size()) {
        throw Error("evaluate_dynamic_filter: detector index " + std::to_string(options.detector) +
                    " out of range (" + std::to_string(f.detections.size()) + " loaded)");
      }
      std::vector<detect::Detection> dets =
          detect::split_by_role(f.detections[static_cast<std::size_t>(options.detector)].boxes,
                                classes, options.mover_min_score)
              .movers;
      for (auto& d : coaster.update(f.t, dets, f.gray.width, f.gray.height)) {
        dets.push_back(std::move(d));
      }
      std::vector<bool> parkable_box;
      for (const auto& d : dets) {
        in.boxes.push_back({d.x_min, d.y_min, d.x_max, d.y_max});
        parkable_box.push_back(parkable.is_dynamic_class(d.label));
      }
      if (options.park_vehicles) parked.assign(f.t, in.boxes, parkable_box);
    }
    last_boxes = in.boxes;
    dynamic::DynamicFilterResult r;
    if (k == 0 || options.filter.mode == dynamic::FilterMode::kOff) {
      // The System keeps every feature of its first frame (nothing to compare with) and with
      // the filter off.
      r.labels.assign(in.points.size(), dynamic::FeatureLabel::kStatic);
      r.reasons.assign(in.points.size(), dynamic::LabelReason::kStaticGeometry);
    } else {
      const auto t0 = std::chrono::steady_clock::now();
      const double cpu0 = thread_cpu_ms();
      set_prev(in, std::max(options.gap, 1));
      dynamic::FlowPyramid cur_pyramid;
      in.prev_pyramid = &last_pyramid;
      in.cur_pyramid_out = &cur_pyramid;
      in.prev_trail = options.gap <= 1 ? &last_trail : nullptr;
      r = dynamic::classify_features(in, options.filter);
      if (options.park_vehicles) parked.observe(r);
      last_pyramid = std::move(cur_pyramid);
      last_trail = r.trail;
      in.prev_pyramid = nullptr;
      in.cur_pyramid_out = nullptr;
      in.prev_trail = nullptr;
      if (options.long_gap > 1 && k > 1) {
        dynamic::DynamicFilterInput far = in;
        set_prev(far, options.long_gap);
        r = dynamic::combine_baselines(r, dynamic::classify_features(far, options.filter),
                                       options.multi_frame);
      }
      out.filter_ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      out.filter_cpu_ms.push_back(thread_cpu_ms() - cpu0);
    }
    out.counts += dynamic::count_removal(in.points, r.labels, f.mask, &r.reasons);
    if (options.on_frame) options.on_frame(f, in, r);
  }
  return out;
}

}  // namespace kestrel::pipeline
