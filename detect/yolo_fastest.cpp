#include "detect/yolo_fastest.hpp"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <opencv2/core/utility.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <stdexcept>

#include "core/error.hpp"
#include "detect/class_names.hpp"
#include "detect/darknet_onednn.hpp"
#include "detect/nms.hpp"
#include "io/cv_image.hpp"
#include "io/image_io.hpp"

namespace kestrel::detect {

namespace fs = std::filesystem;

std::optional<YoloModel> parse_yolo_model(std::string_view text) {
  if (text == "v1.1") return YoloModel::kV11;
  if (text == "xl") return YoloModel::kV11Xl;
  if (text == "body") return YoloModel::kBody;
  return std::nullopt;
}

std::string to_string(YoloModel model) {
  switch (model) {
    case YoloModel::kV11:
      return "v1.1";
    case YoloModel::kV11Xl:
      return "xl";
    case YoloModel::kBody:
      return "body";
  }
  return "?";
}

std::optional<YoloBackend> parse_yolo_backend(std::string_view text) {
  if (text == "onednn") return YoloBackend::kOneDnn;
  if (text == "opencv") return YoloBackend::kOpenCv;
  return std::nullopt;
}

std::string to_string(YoloBackend backend) {
  switch (backend) {
    case YoloBackend::kOneDnn:
      return "onednn";
    case YoloBackend::kOpenCv:
      return "opencv";
  }
  return "?";
}

YoloModelFiles yolo_model_files(const std::string& models_dir, YoloModel model) {
  const fs::path root(models_dir);
  YoloModelFiles f;
  switch (model) {
    case YoloModel::kV11:
      f = {(root / "v1.1_coco/yolo-fastest-1.1.cfg").string(),
           (root / "v1.1_coco/yolo-fastest-1.1.weights").string(),
           (root / "v1.1_coco/coco.names").string()};
      break;
    case YoloModel::kV11Xl:
      f = {(root / "v1.1_coco/yolo-fastest-1.1-xl.cfg").string(),
           (root / "v1.1_coco/yolo-fastest-1.1-xl.weights").string(),
           (root / "v1.1_coco/coco.names").string()};
      break;
    case YoloModel::kBody:
      f = {(root / "v1.1_body/yolo-fastest-1.1_body.cfg").string(),
           (root / "v1.1_body/yolo-fastest-1.1_body.weights").string(),
           (root / "v1.1_body/body.names").string()};
      break;
  }
  for (const std::string* path : {&f.cfg, &f.weights, &f.names}) {
    if (!fs::is_regular_file(*path)) {
      throw Error::at(*path, 0, "", "YOLO-Fastest " + to_string(model) + " model file not found");
    }
  }
  return f;
}

YoloFastestOptions pipeline_yolo_options(YoloModel model) {
  YoloFastestOptions o;
  o.model = model;
  o.conf_threshold = kPipelineYoloMinScore;
  return o;
}

std::string find_models_dir() {
  fs::path shared;
  if (const char* env = std::getenv("KESTREL_SHARED"); env && *env) {
    shared = env;
  } else {
    shared = fs::path(KESTREL_SOURCE_DIR) / ".." / "shared";
  }
  const fs::path dir = (shared / "models" / "yolo-fastest").lexically_normal();
  if (!fs::is_directory(dir)) {
    throw Error::at(dir.string(), 0, "",
                    "YOLO-Fastest models directory not found (set KESTREL_SHARED to the folder "
                    "holding models/yolo-fastest)");
  }
  return dir.string();
}

std::vector<Image> int8_calibration_images(const std::string& data_dir) {
  std::vector<Image> out;
  const fs::path video = fs::path(data_dir) / "video/vtest.avi";
  cv::VideoCapture cap(video.string());
  if (!cap.isOpened()) throw Error::at(video.string(), 0, "", "cannot read the video");
  cv::Mat frame;
  for (int i = 0; i <= 700 && cap.read(frame); ++i) {
    if (i >= 100 && i % 100 == 0) out.push_back(io::to_image(frame.clone()));
  }
  if (out.size() != 7) throw Error::at(video.string(), 0, "", "fewer than 701 frames");
  const fs::path cam0 = fs::path(data_dir) / "euroc/V1_01_micro/mav0/cam0/data";
  if (!fs::is_directory(cam0)) throw Error::at(cam0.string(), 0, "", "folder not found");
  std::vector<fs::path> frames;
  for (const auto& e : fs::directory_iterator(cam0)) {
    if (e.path().extension() == ".png") frames.push_back(e.path());
  }
  std::sort(frames.begin(), frames.end());
  if (frames.empty()) throw Error::at(cam0.string(), 0, "", "no PNG frames");
  for (std::size_t i = 0; i < frames.size(); i += 20) {
    out.push_back(io::load_image(frames[i].string(), io::ImageKind::kGrey));
  }
  return out;
}

struct YoloFastest::Impl {
  std::unique_ptr<DarknetOneDnn> onednn;  // the oneDNN backend, or
  cv::dnn::Net net;                       // the OpenCV one
  std::vector<std::string> output_names;
  std::vector<std::string> class_names;
  std::string model_name;
  cv::Mat blob;  // OpenCV: the NCHW input, reused between frames
  cv::Mat colour, resized;
  std::vector<cv::Mat> outputs;
  std::vector<cv::Mat> channels;

  // colour <- `image` as BGR, resized <- its letterboxed size; returns the letterbox.
  Letterbox resize(const Image& image, int n, InputResize mode) {
    const cv::Mat src = io::as_mat(image);
    if (image.channels == 1) {
      cv::cvtColor(src, colour, cv::COLOR_GRAY2BGR);
    } else {
      colour = src;
    }
    const Letterbox lb = Letterbox::make(image.width, image.height, n, n, mode);
    cv::resize(colour, resized, cv::Size(lb.resized_width, lb.resized_height), 0, 0,
               cv::INTER_LINEAR);
    return lb;
  }

  // The oneDNN input from `resized`: NHWC BGR in [0, 255] (the 1/255 and the swap to RGB are
  // folded into the network); the letterbox padding is Darknet's exact 0.5.
  void fill_onednn_input(const Letterbox& lb, int n, float* dst) {
    cv::Mat in(n, 3 * n, CV_32F, dst);
    if (lb.resized_width != n || lb.resized_height != n) in.setTo(cv::Scalar(127.5));
    resized.reshape(1).convertTo(
        in(cv::Rect(3 * lb.pad_x, lb.pad_y, 3 * lb.resized_width, lb.resized_height)), CV_32F);
  }
};

namespace {
void check_detect_image(const Image& image, const std::string& what) {
  if (image.type != PixelType::kU8 || (image.channels != 1 && image.channels != 3)) {
    throw std::invalid_argument(what + ": image must be 8-bit BGR or grey");
  }
}
}  // namespace

YoloFastest::YoloFastest(const std::string& models_dir, const YoloFastestOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  const std::string where = "YoloFastestOptions";
  if (options.input_size < 32 || options.input_size % 32 != 0) {
    throw Error::at(where, 0, "input_size",
                    "must be a positive multiple of 32, got " + std::to_string(options.input_size));
  }
  if (!(options.conf_threshold >= 0.0f && options.conf_threshold <= 1.0f)) {
    throw Error::at(where, 0, "conf_threshold", "must be in [0, 1]");
  }
  if (!(options.nms_threshold > 0.0f && options.nms_threshold <= 1.0f)) {
    throw Error::at(where, 0, "nms_threshold", "must be in (0, 1]");
  }
  if (options.num_threads < 0) throw Error::at(where, 0, "num_threads", "must not be negative");
  if (options.backend != YoloBackend::kOneDnn && options.backend != YoloBackend::kOpenCv) {
    throw Error::at(where, 0, "backend", "unknown backend");
  }
  const bool int8 = options.precision == YoloPrecision::kInt8;
  if (!int8 && options.precision != YoloPrecision::kFp32) {
    throw Error::at(where, 0, "precision", "unknown precision");
  }
  if (int8 && options.backend != YoloBackend::kOneDnn) {
    throw Error::at(where, 0, "precision", "int8 needs the oneDNN backend");
  }
  if (int8 && options.int8_calibration.empty()) {
    throw Error::at(where, 0, "int8_calibration", "int8 needs calibration images");
  }
  for (const Image& image : options.int8_calibration) {
    if (image.empty()) throw Error::at(where, 0, "int8_calibration", "an image is empty");
    check_detect_image(image, "YoloFastestOptions::int8_calibration");
  }
  const YoloModelFiles files = yolo_model_files(models_dir, options.model);
  impl_->class_names = read_class_names(files.names);
  impl_->model_name =
      "yolo-fastest-" + to_string(options.model) + "@" + std::to_string(options.input_size);
  const int n = options.input_size;
  // Pre-processing runs through OpenCV with either backend.
  if (options.num_threads > 0) cv::setNumThreads(options.num_threads);
  if (options.backend == YoloBackend::kOneDnn) {
    // The network takes the resized 8-bit BGR pixels as they are: the 1/255 and the BGR to RGB
    // swap are folded into its first layer.
    DarknetOneDnnOptions dn;
    dn.threads = options.num_threads;
    dn.input_scale = 1.0f / 255.0f;
    dn.swap_rb = true;
    impl_->onednn = std::make_unique<DarknetOneDnn>(files.cfg, files.weights, n, n, dn);
    if (impl_->onednn->channels() != 3) {
      throw Error::at(files.cfg, 0, "channels", "YOLO-Fastest takes 3-channel input");
    }
    if (impl_->onednn->classes() != static_cast<int>(impl_->class_names.size())) {
      throw Error::at(files.names, 0, "",
                      std::to_string(impl_->class_names.size()) + " class names for a model of " +
                          std::to_string(impl_->onednn->classes()) + " classes (cfg " + files.cfg +
                          ")");
    }
    if (int8) {
      impl_->onednn->quantize_int8(
          [&](std::size_t i, float* in) {
            const Letterbox lb = impl_->resize(options.int8_calibration[i], n, options.resize);
            impl_->fill_onednn_input(lb, n, in);
          },
          options.int8_calibration.size());
      options_.int8_calibration.clear();  // not needed any more
    }
    // The first pass touches every buffer; do it here, not on frame 1.
    std::fill_n(impl_->onednn->input(), static_cast<std::size_t>(3 * n * n), 127.5f);
    impl_->onednn->forward(1.0f);
    return;
  }
  try {
    impl_->net = cv::dnn::readNetFromDarknet(files.cfg, files.weights);
  } catch (const cv::Exception& e) {
    throw Error::at(files.weights, 0, "",
                    "cannot load Darknet model (cfg " + files.cfg + "): " + e.what());
  }
  if (impl_->net.empty()) {
    throw Error::at(files.weights, 0, "", "Darknet model is empty (cfg " + files.cfg + ")");
  }
  impl_->net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  impl_->net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
  impl_->output_names = impl_->net.getUnconnectedOutLayersNames();
  // The first forward pass allocates and fuses layers (tens of ms); do it here, not on frame 1.
  const int shape[] = {1, 3, n, n};
  impl_->blob.create(4, shape, CV_32F);
  impl_->blob.setTo(cv::Scalar(0.5));
  impl_->net.setInput(impl_->blob);
  impl_->net.forward(impl_->outputs, impl_->output_names);
}

YoloFastest::~YoloFastest() = default;

std::string YoloFastest::name() const { return impl_->model_name; }

const std::vector<std::string>& YoloFastest::class_names() const { return impl_->class_names; }

DetectionSet YoloFastest::detect(const Image& image, Timestamp t) {
  const auto start = std::chrono::steady_clock::now();
  DetectionSet out;
  out.t = t;
  if (image.empty()) return out;
  check_detect_image(image, "YoloFastest::detect");
  Impl& m = *impl_;
  const int n = options_.input_size;
  const Letterbox lb = m.resize(image, n, options_.resize);
  std::vector<Detection> candidates;
  const int num_classes = static_cast<int>(m.class_names.size());
  // Region rows: cx, cy, w, h (fractions of the network input), objectness, then one score per
  // class (objectness x probability).
  auto add_row = [&](const float* row) {
    // A class score is objectness x probability, never above the objectness.
    if (row[4] < options_.conf_threshold) return;
    const float* scores = row + 5;
    const int best = static_cast<int>(std::max_element(scores, scores + num_classes) - scores);
    const float score = scores[best];
    if (score < options_.conf_threshold || score <= 0.0f) return;
    const double cx = row[0] * n, cy = row[1] * n, w = row[2] * n, h = row[3] * n;
    Detection d;
    d.label = m.class_names[static_cast<std::size_t>(best)];
    d.class_id = coco_class_id(d.label);
    d.score = score;
    const double W = image.width, H = image.height;
    d.x_min = static_cast<float>(std::clamp(lb.to_image_x(cx - 0.5 * w), 0.0, W));
    d.x_max = static_cast<float>(std::clamp(lb.to_image_x(cx + 0.5 * w), 0.0, W));
    d.y_min = static_cast<float>(std::clamp(lb.to_image_y(cy - 0.5 * h), 0.0, H));
    d.y_max = static_cast<float>(std::clamp(lb.to_image_y(cy + 0.5 * h), 0.0, H));
    if (d.width() <= 0 || d.height() <= 0) return;
    candidates.push_back(std::move(d));
  };

  if (m.onednn) {
    m.fill_onednn_input(lb, n, m.onednn->input());
    for (const YoloHeadRows& head : m.onednn->forward(options_.conf_threshold)) {
      if (head.cols != 5 + num_classes) {
        throw std::runtime_error("YoloFastest: output has " + std::to_string(head.cols) +
                                 " columns, expected " + std::to_string(5 + num_classes));
      }
      for (int r = 0; r < head.rows; ++r) add_row(head.row(r));
    }
  } else {
    // The blob is built by hand rather than with blobFromImage so that the letterbox padding is
    // Darknet's exact 0.5 (an 8-bit canvas can hold only 127 or 128).
    if (lb.resized_width != n || lb.resized_height != n) m.blob.setTo(cv::Scalar(0.5));
    cv::split(m.resized, m.channels);
    const cv::Rect roi(lb.pad_x, lb.pad_y, lb.resized_width, lb.resized_height);
    for (int c = 0; c < 3; ++c) {
      cv::Mat plane(n, n, CV_32F, m.blob.ptr<float>(0, c));
      // The network wants RGB: plane 0 is the image's channel 2.
      m.channels[static_cast<std::size_t>(2 - c)].convertTo(plane(roi), CV_32F, 1.0 / 255.0);
    }
    m.net.setInput(m.blob);
    m.net.forward(m.outputs, m.output_names);
    for (const cv::Mat& o : m.outputs) {
      if (o.dims != 2 || o.cols != 5 + num_classes) {
        throw std::runtime_error("YoloFastest: output has " + std::to_string(o.cols) +
                                 " columns, expected " + std::to_string(5 + num_classes));
      }
      for (int r = 0; r < o.rows; ++r) add_row(o.ptr<float>(r));
    }
  }
  out.boxes = non_max_suppression(candidates, options_.nms_threshold);
  out.latency_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace kestrel::detect
