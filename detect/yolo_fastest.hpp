#pragma once
// YOLO-Fastest 1.1 (Darknet cfg + weights) on the CPU, through oneDNN (DarknetOneDnn, the
// default) or OpenCV DNN. The engines' types stay in the .cpp (pimpl), so this header is cheap
// to include.
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/image.hpp"
#include "detect/detector.hpp"
#include "detect/letterbox.hpp"

namespace kestrel::detect {

enum class YoloModel {
  kV11,    // v1.1_coco/yolo-fastest-1.1      (80 COCO classes, 0.25 BFLOPs at 320)
  kV11Xl,  // v1.1_coco/yolo-fastest-1.1-xl   (80 COCO classes, 0.72 BFLOPs at 320)
  kBody,   // v1.1_body/yolo-fastest-1.1_body (person only)
};

// What kestrel run, the agent and the benches run unless told otherwise: the xl model at 320.
// On rendered scenes it finds what v1.1 calls an umbrella or a keyboard (a car seen from above)
// and more of the people: kestrel bench dynamic, hybrid with YOLO, removed / kept, v1.1 -> xl:
// cafe 88.1 / 88.6 -> 89.5 / 89.2%, market 70.0 / 94.5 -> 79.5 / 94.2%, uav-zigzag
// 43.9 / 90.4 -> 46.1 / 90.5% (at 416 no better: 89.5, 80.5, 45.3% removed; these figures are
// from before the bench gave the filter the IMU's translation as the System does, which moves
// uav-zigzag to 54.1 -> 58.1% and cafe and market by 0.2 pts). It costs about
// 8 ms a frame on the detection thread's core against 5 ms, well inside a 30 Hz frame.
// Measured again with today's filter (the bench's 12 s, removed / kept): at 416 with a class
// score of 0.10 instead of 320 and 0.25, uav-zigzag 58.7 / 95.4 -> 66.0 / 95.0%, market 81.0 /
// 94.4 -> 83.4 / 94.2%, cafe 89.6 / 90.4 -> 90.1 / 90.4%; but over nine 60 s draws (market and
// cafe seeds 1-3, uav-zigzag seeds 1, 4, 5) APE summed 0.33 -> 0.42 m, worse on six (uav-zigzag
// seed 4 0.038 -> 0.118 m), better on three, so 320 and 0.25 stay.
inline constexpr YoloModel kPipelineYoloModel = YoloModel::kV11Xl;

// "v1.1", "xl", "body" (the CLI's --model values); nullopt for anything else.
std::optional<YoloModel> parse_yolo_model(std::string_view text);
std::string to_string(YoloModel model);

// The inference engine. Both read the same Darknet files and give the same boxes (scores agree
// to about 1e-3); on one core of the development machine (AMD EPYC, AVX-512) v1.1 at 320 takes
// about 5.5 ms per forward pass with oneDNN and 11.5 ms with OpenCV DNN 4.6 (bench_detect).
enum class YoloBackend {
  kOneDnn,  // DarknetOneDnn: folded batch norm, fused activations and shortcuts, NHWC fp32
  kOpenCv,  // cv::dnn::readNetFromDarknet, DNN_BACKEND_OPENCV on the CPU
};

// "onednn", "opencv" (the CLI's --backend values); nullopt for anything else.
std::optional<YoloBackend> parse_yolo_backend(std::string_view text);
std::string to_string(YoloBackend backend);

// The oneDNN backend's arithmetic. Int8 runs the wide inner activations of the network in 8
// bits (DarknetOneDnn::quantize_int8), calibrated at construction on the images in
// YoloFastestOptions::int8_calibration.
enum class YoloPrecision { kFp32, kInt8 };

struct YoloModelFiles {
  std::string cfg, weights, names;
};
// The three files of `model` under `models_dir` (.../models/yolo-fastest). Throws
// kestrel::Error naming the first file that does not exist.
YoloModelFiles yolo_model_files(const std::string& models_dir, YoloModel model);

// .../shared/models/yolo-fastest: $KESTREL_SHARED/models/yolo-fastest if KESTREL_SHARED is set,
// else ../shared/models/yolo-fastest beside the source tree. Throws kestrel::Error naming the
// directory when it does not exist.
std::string find_models_dir();

// The int8 calibration set used by the tests and benches, real frames disjoint from every image
// the detector tests check: frames 100, 200, ..., 700 of data/video/vtest.avi (pedestrians seen
// from above, 768x576) and every 20th frame of data/euroc/V1_01_micro/mav0/cam0 (grey, indoor),
// 12 images. `data_dir` is the shared data folder (find_models_dir()/../../data). Throws
// kestrel::Error naming the file or folder that cannot be read.
std::vector<Image> int8_calibration_images(const std::string& data_dir);

struct YoloFastestOptions {
  YoloModel model = YoloModel::kV11;
  int input_size = 320;  // network input, square; a multiple of 32 (320 or 416 in practice)
  YoloBackend backend = YoloBackend::kOneDnn;
  YoloPrecision precision = YoloPrecision::kFp32;  // int8 needs the oneDNN backend
  // Int8 only: the calibration images (8-bit BGR or grey, any size), pre-processed as detect()
  // does; they set each quantized activation's range. Required (non-empty) for int8.
  std::vector<Image> int8_calibration;
  // Minimum class score (objectness x class probability). With the OpenCV backend values below
  // 0.2 act as 0.2 (its Region layer zeroes lower scores); oneDNN honours any value.
  float conf_threshold = 0.25f;
  float nms_threshold = 0.45f;  // IoU above which the weaker box of a class is dropped (Darknet's)
  // Stretch matches training; letterbox keeps the aspect ratio (see letterbox.hpp).
  InputResize resize = InputResize::kStretch;
  // Threads when > 0: cv::setNumThreads() at construction (process-wide in OpenCV; it runs the
  // pre-processing, and the network with the OpenCV backend) and, for oneDNN, the OpenMP thread
  // count its primitives are built for and run with (see DarknetOneDnn; per thread). The
  // default 1 suits the pipeline, where detection runs on its own core; 0 leaves the libraries'
  // settings alone.
  int num_threads = 1;
};

// The pipeline's detector reports boxes from this class score up. Chairs and tables score low
// (YOLO-Fastest xl calls cafe's rendered chairs chairs at 0.1-0.2, seldom above 0.25), and the
// object database asks several views to agree before it reports one; movers' boxes still need
// kMoverMinScore (dynamic_classes.hpp), so the dynamic filter and the trajectory are unchanged.
// Eight draws of the scenarios' own length (cafe seeds 1-4, 30 s; market 1-3, 50 s; ugv-loop,
// 60 s; kestrel run, objects against the world), 0.25 -> 0.15: 19 -> 27 of 56 truth objects
// found, with 27 -> 40 reports of which 19 -> 27 right; the trajectories the same to the byte.
// At 0.10: 29 found, 54 reports (29 right); at 0.07 (cafe 1-2, market 1, ugv-loop) 16 of 28
// found, 35 reports.
inline constexpr float kPipelineYoloMinScore = 0.15f;

// What kestrel run, the agent and the benches build their detector with: `model` at 320, one
// thread, boxes from kPipelineYoloMinScore up.
YoloFastestOptions pipeline_yolo_options(YoloModel model = kPipelineYoloModel);

class YoloFastest final : public Detector {
 public:
  // Loads the model from `models_dir` (see yolo_model_files). Throws kestrel::Error naming the
  // file when one is missing or cannot be parsed, and for bad options.
  explicit YoloFastest(const std::string& models_dir, const YoloFastestOptions& options = {});
  ~YoloFastest() override;
  YoloFastest(const YoloFastest&) = delete;
  YoloFastest& operator=(const YoloFastest&) = delete;

  DetectionSet detect(const Image& image, Timestamp t) override;
  std::string name() const override;

  const YoloFastestOptions& options() const { return options_; }
  const std::vector<std::string>& class_names() const;

 private:
  struct Impl;
  YoloFastestOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::detect
