// Detector speed: ms per frame on one thread (the pipeline gives detection its own core).
// Every benchmark times each iteration itself and reports the median (p50_ms), the fastest
// (min_ms) and p90 over 300 iterations, in wall time and in the thread's CPU time (cpu_p50_ms:
// the time it ran, without the time other processes had the core): on a shared machine the mean
// mostly measures the neighbours. Run it alone (flock /tmp/kestrel-build.lock
// build/bench/bench_detect).
//  - BM_YoloFastest: YoloFastest::detect (pre-processing, network, decoding, NMS) on the TUM
//    frame, v1.1 and XL at 320 and 416 and the body model, with either backend.
//  - BM_Interleaved: v1.1@320 with the two backends alternating frame by frame, so that both
//    medians see the same machine load: the fairest comparison on a busy machine.
//  - BM_Precision: v1.1@320 detect() on oneDNN, fp32 and int8 (calibrated on
//    int8_calibration_images) alternating.
//  - BM_Forward: the network alone, v1.1@320: OpenCV DNN fused (its default), without fusion,
//    OpenCV's int8 path (Net::quantize, calibrated on the shared sample photos), oneDNN fp32
//    and oneDNN int8.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <opencv2/core/utility.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "core/thread_cpu_time.hpp"
#include "detect/darknet_onednn.hpp"
#include "detect/yolo_fastest.hpp"
#include "io/cv_image.hpp"
#include "io/image_io.hpp"

namespace {

using namespace kestrel;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

fs::path shared_data(const std::string& rel) {
  // find_models_dir() is <shared>/models/yolo-fastest.
  return fs::path(detect::find_models_dir()) / ".." / ".." / "data" / rel;
}

const std::string kFrame = "tum_fr3/frame/rgb_1341846313.592026.png";
constexpr int kIterations = 300;

// Wall and thread-CPU milliseconds of each timed iteration.
struct Samples {
  std::vector<double> wall, cpu;
};

// Times `f` once into `s`.
template <class F>
void timed(Samples& s, F&& f) {
  const double c0 = thread_cpu_ms();
  const auto t0 = Clock::now();
  f();
  s.wall.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  s.cpu.push_back(thread_cpu_ms() - c0);
}

void report(benchmark::State& state, Samples s, const std::string& prefix = "") {
  if (s.wall.empty()) return;
  std::sort(s.wall.begin(), s.wall.end());
  std::sort(s.cpu.begin(), s.cpu.end());
  state.counters[prefix + "p50_ms"] = s.wall[s.wall.size() / 2];
  state.counters[prefix + "min_ms"] = s.wall.front();
  state.counters[prefix + "p90_ms"] = s.wall[s.wall.size() * 9 / 10];
  state.counters[prefix + "cpu_p50_ms"] = s.cpu[s.cpu.size() / 2];
}

detect::YoloFastestOptions options(int model, int size, int backend) {
  detect::YoloFastestOptions o;
  o.model = static_cast<detect::YoloModel>(model);
  o.input_size = size;
  o.backend = static_cast<detect::YoloBackend>(backend);
  o.num_threads = 1;
  return o;
}

void BM_YoloFastest(benchmark::State& state) {
  const auto o = options(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
                         static_cast<int>(state.range(2)));
  detect::YoloFastest detector(detect::find_models_dir(), o);
  const Image image = io::load_image(shared_data(kFrame).string(), io::ImageKind::kColor);
  std::size_t boxes = 0;
  Samples ms;
  for (auto _ : state) {
    timed(ms, [&] { boxes = detector.detect(image, 0).boxes.size(); });
    benchmark::DoNotOptimize(boxes);
  }
  state.SetLabel(detector.name() + " " + detect::to_string(o.backend));
  state.counters["boxes"] = static_cast<double>(boxes);
  report(state, ms);
}
void YoloArgs(benchmark::internal::Benchmark* b) {
  b->ArgNames({"model", "size", "backend"});
  for (int backend : {static_cast<int>(detect::YoloBackend::kOneDnn),
                      static_cast<int>(detect::YoloBackend::kOpenCv)}) {
    b->Args({static_cast<int>(detect::YoloModel::kV11), 320, backend});
    b->Args({static_cast<int>(detect::YoloModel::kV11), 416, backend});
    b->Args({static_cast<int>(detect::YoloModel::kV11Xl), 320, backend});
    b->Args({static_cast<int>(detect::YoloModel::kV11Xl), 416, backend});
    b->Args({static_cast<int>(detect::YoloModel::kBody), 320, backend});
  }
}
BENCHMARK(BM_YoloFastest)->Apply(YoloArgs)->Unit(benchmark::kMillisecond)->Iterations(kIterations);

void BM_Interleaved(benchmark::State& state) {
  const int v11 = static_cast<int>(detect::YoloModel::kV11);
  detect::YoloFastest onednn(detect::find_models_dir(),
                             options(v11, 320, static_cast<int>(detect::YoloBackend::kOneDnn)));
  detect::YoloFastest opencv(detect::find_models_dir(),
                             options(v11, 320, static_cast<int>(detect::YoloBackend::kOpenCv)));
  const Image image = io::load_image(shared_data(kFrame).string(), io::ImageKind::kColor);
  Samples a, b;
  for (auto _ : state) {
    timed(a, [&] { benchmark::DoNotOptimize(onednn.detect(image, 0).boxes.size()); });
    timed(b, [&] { benchmark::DoNotOptimize(opencv.detect(image, 0).boxes.size()); });
  }
  state.SetLabel("v1.1@320 detect(), oneDNN and OpenCV alternating");
  report(state, a, "onednn_");
  report(state, b, "opencv_");
}
BENCHMARK(BM_Interleaved)->Unit(benchmark::kMillisecond)->Iterations(kIterations);

void BM_Precision(benchmark::State& state) {
  detect::YoloFastest fp32(detect::find_models_dir());
  detect::YoloFastestOptions o;
  o.precision = detect::YoloPrecision::kInt8;
  o.int8_calibration = detect::int8_calibration_images(shared_data("").string());
  detect::YoloFastest int8(detect::find_models_dir(), o);
  const Image image = io::load_image(shared_data(kFrame).string(), io::ImageKind::kColor);
  Samples a, b;
  for (auto _ : state) {
    timed(a, [&] { benchmark::DoNotOptimize(fp32.detect(image, 0).boxes.size()); });
    timed(b, [&] { benchmark::DoNotOptimize(int8.detect(image, 0).boxes.size()); });
  }
  state.SetLabel("v1.1@320 detect(), oneDNN fp32 and int8 alternating");
  report(state, a, "fp32_");
  report(state, b, "int8_");
}
BENCHMARK(BM_Precision)->Unit(benchmark::kMillisecond)->Iterations(kIterations);

cv::Mat input_blob(const cv::Mat& bgr, int size) {
  return cv::dnn::blobFromImage(bgr, 1.0 / 255.0, cv::Size(size, size), cv::Scalar(), true, false);
}

// The network alone, v1.1 at 320: variant 0 = OpenCV fused (its default), 1 = OpenCV without
// fusion, 2 = OpenCV int8, 3 = oneDNN fp32 (DarknetOneDnn), 4 = oneDNN int8.
void BM_Forward(benchmark::State& state) {
  cv::setNumThreads(1);
  const detect::YoloModelFiles f =
      detect::yolo_model_files(detect::find_models_dir(), detect::YoloModel::kV11);
  const int size = 320;
  const cv::Mat blob = input_blob(cv::imread(shared_data(kFrame).string()), size);
  Samples ms;
  if (state.range(0) >= 3) {
    detect::DarknetOneDnn net(f.cfg, f.weights, size, size);
    auto fill = [&](const cv::Mat& b, float* in) {
      for (int c = 0; c < 3; ++c) {
        for (int y = 0; y < size; ++y) {
          for (int x = 0; x < size; ++x) in[(y * size + x) * 3 + c] = b.ptr<float>(0, c, y)[x];
        }
      }
    };
    if (state.range(0) == 4) {
      std::vector<cv::Mat> calib;
      for (const Image& image : detect::int8_calibration_images(shared_data("").string())) {
        cv::Mat bgr = io::as_mat(image);
        if (image.channels == 1) cv::cvtColor(bgr, bgr, cv::COLOR_GRAY2BGR);
        calib.push_back(input_blob(bgr, size));
      }
      net.quantize_int8([&](std::size_t i, float* in) { fill(calib[i], in); }, calib.size());
    }
    fill(blob, net.input());
    for (auto _ : state) {
      timed(ms, [&] { benchmark::DoNotOptimize(net.forward(0.25f).data()); });
    }
  } else {
    cv::dnn::Net net = cv::dnn::readNetFromDarknet(f.cfg, f.weights);
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
    net.setInput(blob);
    net.forward(result, outs);  // allocation and fusion happen on the first pass
    for (auto _ : state) {
      timed(ms, [&] {
        net.setInput(blob);
        net.forward(result, outs);
      });
      benchmark::DoNotOptimize(result.data());
    }
  }
  static const char* kNames[] = {"OpenCV fp32 fused", "OpenCV fp32 no fusion",
                                 "OpenCV int8 (Net::quantize)", "oneDNN fp32", "oneDNN int8"};
  state.SetLabel(kNames[state.range(0)]);
  report(state, ms);
}
BENCHMARK(BM_Forward)->DenseRange(0, 4)->Unit(benchmark::kMillisecond)->Iterations(kIterations);

}  // namespace
