// Detector speed: ms per frame on one thread (the pipeline gives detection its own core).
// YOLO-Fastest v1.1 and XL at 320 and 416 through YoloFastest (pre-processing, network, NMS),
// plus the OpenCV DNN variants tried for speed: the network alone with and without layer
// fusion, and OpenCV's int8 path (Net::quantize calibrated on the shared sample photos).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <opencv2/core/utility.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "detect/yolo_fastest.hpp"
#include "io/image_io.hpp"

namespace {

using namespace kestrel;
namespace fs = std::filesystem;

fs::path shared_data(const std::string& rel) {
  // find_models_dir() is <shared>/models/yolo-fastest.
  return fs::path(detect::find_models_dir()) / ".." / ".." / "data" / rel;
}

const std::string kFrame = "tum_fr3/frame/rgb_1341846313.592026.png";

void BM_YoloFastest(benchmark::State& state) {
  detect::YoloFastestOptions o;
  o.model = static_cast<detect::YoloModel>(state.range(0));
  o.input_size = static_cast<int>(state.range(1));
  o.num_threads = 1;
  detect::YoloFastest detector(detect::find_models_dir(), o);
  const Image image = io::load_image(shared_data(kFrame).string(), io::ImageKind::kColor);
  std::size_t boxes = 0;
  for (auto _ : state) {
    boxes = detector.detect(image, 0).boxes.size();
    benchmark::DoNotOptimize(boxes);
  }
  state.SetLabel(detector.name());
  state.counters["boxes"] = static_cast<double>(boxes);
}
BENCHMARK(BM_YoloFastest)
    ->ArgNames({"model", "size"})
    ->Args({static_cast<int>(detect::YoloModel::kV11), 320})
    ->Args({static_cast<int>(detect::YoloModel::kV11), 416})
    ->Args({static_cast<int>(detect::YoloModel::kV11Xl), 320})
    ->Args({static_cast<int>(detect::YoloModel::kV11Xl), 416})
    ->Args({static_cast<int>(detect::YoloModel::kBody), 320})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0);

cv::Mat input_blob(const cv::Mat& bgr, int size) {
  return cv::dnn::blobFromImage(bgr, 1.0 / 255.0, cv::Size(size, size), cv::Scalar(), true, false);
}

// Raw OpenCV DNN forward pass of v1.1 at 320: variant 0 = fused (the default), 1 = without
// fusion, 2 = int8.
void BM_OpenCvVariant(benchmark::State& state) {
  cv::setNumThreads(1);
  const detect::YoloModelFiles f =
      detect::yolo_model_files(detect::find_models_dir(), detect::YoloModel::kV11);
  cv::dnn::Net net = cv::dnn::readNetFromDarknet(f.cfg, f.weights);
  const int size = 320;
  const cv::Mat blob = input_blob(cv::imread(shared_data(kFrame).string()), size);
  if (state.range(0) == 1) net.enableFusion(false);
  if (state.range(0) == 2) {
    std::vector<cv::Mat> calib;
    for (const char* name :
         {"person.jpg", "dog.jpg", "horses.jpg", "000004.jpg", "000139.jpg", "000230.jpg"}) {
      calib.push_back(cv::imread(shared_data(std::string("images/") + name).string()));
    }
    net = net.quantize(cv::dnn::blobFromImages(calib, 1.0 / 255.0, cv::Size(size, size),
                                               cv::Scalar(), true, false),
                       CV_32F, CV_32F);
  }
  const std::vector<std::string> outs = net.getUnconnectedOutLayersNames();
  std::vector<cv::Mat> result;
  for (auto _ : state) {
    net.setInput(blob);
    net.forward(result, outs);
    benchmark::DoNotOptimize(result.data());
  }
  static const char* kNames[] = {"fp32 fused", "fp32 no fusion", "int8 (Net::quantize)"};
  state.SetLabel(kNames[state.range(0)]);
}
BENCHMARK(BM_OpenCvVariant)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
