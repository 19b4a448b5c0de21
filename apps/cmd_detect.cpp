// `kestrel detect IMAGE...`: YOLO-Fastest on still images; prints the boxes, optionally draws
// them (--out) and writes them as JSON (--json). Flags only; the work is in detect/.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "apps/commands.hpp"
#include "detect/detection_json.hpp"
#include "detect/draw_detections.hpp"
#include "detect/yolo_fastest.hpp"
#include "io/image_io.hpp"

namespace {

using namespace kestrel;

struct DetectArgs {
  std::vector<std::string> images;
  std::string model = "v1.1";
  int size = 320;
  float conf = 0.25f;
  float nms = 0.45f;
  bool letterbox = false;
  std::string backend = "onednn";
  std::string precision = "fp32";
  int threads = 1;
  std::string models_dir;
  std::string out;
  std::string json;
};

// With several images, --out a.png becomes a_<image stem>.png for each.
std::string annotated_path(const std::string& out, const std::string& image, bool several) {
  if (!several) return out;
  const std::filesystem::path o(out);
  const std::string stem = std::filesystem::path(image).stem().string();
  return (o.parent_path() / (o.stem().string() + "_" + stem + o.extension().string())).string();
}

void run_detect(const DetectArgs& a) {
  detect::YoloFastestOptions o;
  o.model = *detect::parse_yolo_model(a.model);  // CLI::IsMember checked it
  o.input_size = a.size;
  o.conf_threshold = a.conf;
  o.nms_threshold = a.nms;
  o.resize = a.letterbox ? detect::InputResize::kLetterbox : detect::InputResize::kStretch;
  o.backend = *detect::parse_yolo_backend(a.backend);  // CLI::IsMember checked it
  o.num_threads = a.threads;
  const std::string models = a.models_dir.empty() ? detect::find_models_dir() : a.models_dir;
  if (a.precision == "int8") {
    o.precision = detect::YoloPrecision::kInt8;
    o.int8_calibration = detect::int8_calibration_images(
        (std::filesystem::path(models) / ".." / ".." / "data").lexically_normal().string());
  }
  detect::YoloFastest detector(models, o);

  std::vector<detect::LabelledDetectionSet> results;
  for (const std::string& path : a.images) {
    const Image image = io::load_image(path, io::ImageKind::kColor);
    detect::LabelledDetectionSet r{path, detector.detect(image, 0)};
    std::printf("%s: %zu boxes, %.1f ms (%s)\n", path.c_str(), r.set.boxes.size(), r.set.latency_ms,
                detector.name().c_str());
    for (const detect::Detection& d : r.set.boxes) {
      std::printf("  %-14s %.3f  %7.1f %7.1f %7.1f %7.1f\n", d.label.c_str(),
                  static_cast<double>(d.score), static_cast<double>(d.x_min),
                  static_cast<double>(d.y_min), static_cast<double>(d.x_max),
                  static_cast<double>(d.y_max));
    }
    if (!a.out.empty()) {
      const std::string out = annotated_path(a.out, path, a.images.size() > 1);
      io::write_png(out, detect::draw_detections(image, r.set.boxes));
      std::printf("  annotated: %s\n", out.c_str());
    }
    results.push_back(std::move(r));
  }
  if (!a.json.empty()) detect::write_detections_json(a.json, results);
}

void setup_detect(CLI::App& app) {
  auto args = std::make_shared<DetectArgs>();
  auto* cmd = app.add_subcommand("detect", "Detect objects in images with YOLO-Fastest");
  cmd->add_option("IMAGE", args->images, "images to run on (PNG, JPEG, ...)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--model", args->model, "v1.1 (COCO), xl (COCO, larger) or body (persons)")
      ->check(CLI::IsMember({"v1.1", "xl", "body"}));
  cmd->add_option("--size", args->size, "network input size in pixels")
      ->check(CLI::IsMember({320, 416}));
  cmd->add_option("--backend", args->backend,
                  "onednn (default, about twice as fast on one core) or opencv (OpenCV DNN)")
      ->check(CLI::IsMember({"onednn", "opencv"}));
  cmd->add_option("--precision", args->precision,
                  "fp32 (default) or int8 (oneDNN only; about 25% faster, keeps about 97% of the "
                  "fp32 boxes; calibrated on the shared data's vtest.avi and EuRoC frames)")
      ->check(CLI::IsMember({"fp32", "int8"}));
  cmd->add_option("--conf", args->conf,
                  "minimum class score (with --backend opencv values below 0.2 act as 0.2)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--nms", args->nms, "per-class NMS IoU threshold")->check(CLI::Range(0.01, 1.0));
  cmd->add_flag("--letterbox", args->letterbox,
                "keep the aspect ratio (Darknet letterbox) instead of stretching to the input");
  cmd->add_option("--threads", args->threads,
                  "threads for the network and pre-processing (0 = the libraries' defaults)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--models", args->models_dir,
                  "models/yolo-fastest directory (default: $KESTREL_SHARED or ../shared)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out,
                  "write the image with its boxes drawn (PNG); with several images the image's "
                  "name is appended");
  cmd->add_option("--json", args->json, "write the detections as JSON");
  cmd->callback([args] { run_detect(*args); });
}

}  // namespace

KESTREL_COMMAND(40, setup_detect);
