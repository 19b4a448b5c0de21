// DarknetOneDnn against OpenCV DNN's Darknet reader on the real YOLO-Fastest weights and on a
// small random network that uses every layer kind the reader accepts; YoloFastest's two
// backends on the real test images; and the reader's errors.
#include "detect/darknet_onednn.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <opencv2/core/utility.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "detect/nms.hpp"
#include "detect/yolo_fastest.hpp"
#include "io/cv_image.hpp"
#include "io/image_io.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::detect {
namespace {

namespace fs = std::filesystem;

std::string models_dir() { return (test::shared_dir() / "models/yolo-fastest").string(); }

// The NCHW blob OpenCV takes and the same pixels as DarknetOneDnn's NHWC input.
void fill_nhwc(const cv::Mat& blob, float* nhwc) {
  const int c = blob.size[1], h = blob.size[2], w = blob.size[3];
  for (int k = 0; k < c; ++k) {
    for (int y = 0; y < h; ++y) {
      const float* row = blob.ptr<float>(0, k, y);
      for (int x = 0; x < w; ++x) nhwc[(static_cast<std::size_t>(y) * w + x) * c + k] = row[x];
    }
  }
}

// Largest differences: centres (fractions of the input), sizes (relative), objectness and
// class scores (absolute).
struct RowDiff {
  double centres = 0, sizes = 0, objectness = 0, classes = 0;
};

// OpenCV's Region layer zeroes class scores below 0.2 (its default threshold); the same is
// applied to DarknetOneDnn's rows (forward(0) leaves every score in) before comparing, and
// scores within 0.01 of 0.2, which may fall on either side of it, are left out.
RowDiff compare_with_opencv(const std::string& cfg, const std::string& weights, int width,
                            int height, const std::vector<cv::Mat>& blobs, float floor = 0.2f) {
  cv::setNumThreads(1);
  DarknetOneDnn net(cfg, weights, width, height);
  cv::dnn::Net cvnet = cv::dnn::readNetFromDarknet(cfg, weights);
  cvnet.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  RowDiff d;
  for (const cv::Mat& blob : blobs) {
    fill_nhwc(blob, net.input());
    const std::vector<YoloHeadRows>& mine = net.forward(0.0f);
    cvnet.setInput(blob);
    std::vector<cv::Mat> theirs;
    cvnet.forward(theirs, cvnet.getUnconnectedOutLayersNames());
    EXPECT_EQ(mine.size(), theirs.size());
    if (mine.size() != theirs.size()) return {1e9, 1e9, 1e9, 1e9};
    for (std::size_t k = 0; k < mine.size(); ++k) {
      EXPECT_EQ(mine[k].rows, theirs[k].rows) << "head " << k;
      EXPECT_EQ(mine[k].cols, theirs[k].cols) << "head " << k;
      if (mine[k].rows != theirs[k].rows || mine[k].cols != theirs[k].cols)
        return {1e9, 1e9, 1e9, 1e9};
      for (int r = 0; r < mine[k].rows; ++r) {
        const float* a = mine[k].row(r);
        const float* b = theirs[k].ptr<float>(r);
        for (int c = 0; c < 2; ++c) d.centres = std::max(d.centres, std::abs(double(a[c]) - b[c]));
        for (int c = 2; c < 4; ++c) {
          d.sizes = std::max(d.sizes, std::abs(double(a[c]) - b[c]) / std::max(1e-6, double(b[c])));
        }
        d.objectness = std::max(d.objectness, std::abs(double(a[4]) - b[4]));
        for (int c = 5; c < mine[k].cols; ++c) {
          if (std::abs(a[c] - floor) < 0.01f) continue;
          const float ours = a[c] < floor ? 0.0f : a[c];
          d.classes = std::max(d.classes, std::abs(double(ours) - b[c]));
        }
      }
    }
  }
  return d;
}

cv::Mat blob_of(const std::string& rel, int size) {
  const cv::Mat bgr = cv::imread(test::shared_data(rel).string());
  EXPECT_FALSE(bgr.empty()) << rel;
  return cv::dnn::blobFromImage(bgr, 1.0 / 255.0, cv::Size(size, size), cv::Scalar(), true, false);
}

const std::vector<std::string> kImages = {"tum_fr3/frame/rgb_1341846313.592026.png",
                                          "images/person.jpg",
                                          "images/dog.jpg",
                                          "images/horses.jpg",
                                          "images/000004.jpg",
                                          "images/000230.jpg"};

TEST(DarknetOneDnn, RealModelsMatchOpenCvRowForRow) {
  struct Case {
    YoloModel model;
    int size;
  };
  for (const Case& c : {Case{YoloModel::kV11, 320}, Case{YoloModel::kV11, 416},
                        Case{YoloModel::kV11Xl, 320}, Case{YoloModel::kBody, 320}}) {
    const YoloModelFiles f = yolo_model_files(models_dir(), c.model);
    std::vector<cv::Mat> blobs;
    for (const std::string& rel : kImages) blobs.push_back(blob_of(rel, c.size));
    const RowDiff d = compare_with_opencv(f.cfg, f.weights, c.size, c.size, blobs);
    std::cout << to_string(c.model) << "@" << c.size << " max |oneDNN - OpenCV|: centres "
              << d.centres << ", sizes " << d.sizes << " (relative), objectness " << d.objectness
              << ", class scores " << d.classes << "\n";
    // Float summation order differs; a different layer or layout would differ by far more.
    EXPECT_LT(d.centres, 2e-3) << to_string(c.model);
    EXPECT_LT(d.sizes, 1e-2) << to_string(c.model);
    EXPECT_LT(d.objectness, 5e-3) << to_string(c.model);
    EXPECT_LT(d.classes, 5e-3) << to_string(c.model);
  }
}

// ---- a small random network ------------------------------------------------------------------

struct ConvSpec {
  int filters, in_per_group, size;
  bool bn;
};

void write_weights(const fs::path& path, const std::vector<ConvSpec>& convs, unsigned seed,
                   int extra_floats = 0, int missing_floats = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f), pos(0.5f, 1.5f);
  std::vector<float> v;
  for (const ConvSpec& c : convs) {
    for (int f = 0; f < c.filters; ++f) v.push_back(u(rng));  // biases
    if (c.bn) {
      for (int f = 0; f < c.filters; ++f) v.push_back(pos(rng));       // scales
      for (int f = 0; f < c.filters; ++f) v.push_back(0.2f * u(rng));  // means
      for (int f = 0; f < c.filters; ++f) v.push_back(pos(rng));       // variances
    }
    const int n = c.filters * c.in_per_group * c.size * c.size;
    const float s = 1.5f / std::sqrt(static_cast<float>(c.in_per_group * c.size * c.size));
    for (int k = 0; k < n; ++k) v.push_back(s * u(rng));
  }
  for (int k = 0; k < extra_floats; ++k) v.push_back(0.0f);
  v.resize(v.size() - static_cast<std::size_t>(missing_floats));
  std::ofstream out(path, std::ios::binary);
  const std::int32_t header[3] = {0, 2, 5};
  const std::uint64_t seen = 0;
  out.write(reinterpret_cast<const char*>(header), sizeof header);
  out.write(reinterpret_cast<const char*>(&seen), sizeof seen);
  out.write(reinterpret_cast<const char*>(v.data()),
            static_cast<std::streamsize>(v.size() * sizeof(float)));
}

// Every layer kind: a fused shortcut (conv -> dropout -> shortcut), an unfused one (its input
// is also routed later), grouped and depthwise convolutions, a stride-2 and an SPP max pool,
// upsample, multi-layer routes with relative and absolute indices, two [yolo] heads.
const char* kSmallCfg = R"([net]
width=64
height=64
channels=3

# 0
[convolutional]
filters=8
size=3
stride=2
pad=1
batch_normalize=1
activation=leaky

# 1 depthwise
[convolutional]
filters=8
groups=8
size=3
pad=1
batch_normalize=1
activation=leaky

# 2
[convolutional]
filters=8
size=1
batch_normalize=1
activation=linear

# 3
[dropout]
probability=.1

# 4 fused into 2
[shortcut]
from=-4
activation=linear

# 5 grouped
[convolutional]
filters=16
groups=2
size=3
stride=1
pad=1
batch_normalize=1
activation=leaky

# 6
[convolutional]
filters=16
size=1
activation=linear

# 7 not fused: layer 6 is routed below too
[shortcut]
from=-2
activation=linear

# 8
[maxpool]
size=2
stride=2

# 9 SPP
[maxpool]
size=5
stride=1

# 10
[route]
layers=-1,-2

# 11
[convolutional]
filters=14
size=1
activation=linear

# 12
[yolo]
mask=1,0
anchors=8,9, 20,24, 40,36
classes=2
num=3
scale_x_y=1.05

# 13
[route]
layers=10

# 14
[upsample]
stride=2

# 15
[route]
layers=-1, 6, 4

# 16
[convolutional]
filters=7
size=5
pad=1
activation=linear

# 17
[yolo]
mask=2
anchors=8,9, 20,24, 40,36
classes=2
num=3
)";

const std::vector<ConvSpec> kSmallConvs = {{8, 3, 3, true},  {8, 1, 3, true},    {8, 8, 1, true},
                                           {16, 4, 3, true}, {16, 16, 1, false}, {14, 32, 1, false},
                                           {7, 56, 5, false}};

struct SmallNet {
  fs::path cfg, weights;
};

SmallNet small_net(const std::string& name, const std::string& cfg_text = kSmallCfg, int extra = 0,
                   int missing = 0) {
  const fs::path dir = test::temp_dir(name);
  SmallNet n{dir / "small.cfg", dir / "small.weights"};
  std::ofstream(n.cfg) << cfg_text;
  write_weights(n.weights, kSmallConvs, 7, extra, missing);
  return n;
}

TEST(DarknetOneDnn, EveryLayerKindMatchesOpenCv) {
  const SmallNet n = small_net("darknet_small");
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<cv::Mat> blobs;
  for (int k = 0; k < 3; ++k) {
    const int shape[] = {1, 3, 64, 64};
    cv::Mat blob(4, shape, CV_32F);
    for (auto it = blob.begin<float>(); it != blob.end<float>(); ++it) *it = u(rng);
    blobs.push_back(blob);
  }
  const RowDiff d = compare_with_opencv(n.cfg.string(), n.weights.string(), 64, 64, blobs);
  std::cout << "small net max |oneDNN - OpenCV|: centres " << d.centres << ", sizes " << d.sizes
            << ", objectness " << d.objectness << ", class scores " << d.classes << "\n";
  EXPECT_LT(d.centres, 1e-4);
  EXPECT_LT(d.sizes, 1e-4);
  EXPECT_LT(d.objectness, 1e-4);
  EXPECT_LT(d.classes, 1e-4);

  DarknetOneDnn net(n.cfg.string(), n.weights.string(), 64, 64);
  EXPECT_EQ(net.channels(), 3);
  EXPECT_EQ(net.classes(), 2);
  const std::string summary = net.summary();
  EXPECT_NE(summary.find("4 shortcut 0 (fused)"), std::string::npos) << summary;
  EXPECT_NE(summary.find("7 shortcut 5\n"), std::string::npos) << summary;
  // Rows per head: 16x16 cells x 2 anchors, then 32x32 x 1.
  fill_nhwc(blobs.front(), net.input());
  const auto& rows = net.forward(0.0f);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].rows, 16 * 16 * 2);
  EXPECT_EQ(rows[1].rows, 32 * 32 * 1);
  EXPECT_EQ(rows[0].cols, 7);
}

TEST(DarknetOneDnn, ScoreFloorOnlyZeroesRowsThatCannotReachIt) {
  const SmallNet n = small_net("darknet_floor");
  DarknetOneDnn net(n.cfg.string(), n.weights.string(), 64, 64);
  std::fill_n(net.input(), 64 * 64 * 3, 0.3f);
  const std::vector<YoloHeadRows> all = net.forward(0.0f);
  const std::vector<YoloHeadRows> floored = net.forward(0.5f);
  int zeroed = 0, kept = 0;
  for (std::size_t k = 0; k < all.size(); ++k) {
    for (int r = 0; r < all[k].rows; ++r) {
      const float* a = all[k].row(r);
      const float* b = floored[k].row(r);
      for (int c = 0; c < 5; ++c) EXPECT_FLOAT_EQ(a[c], b[c]);
      for (int c = 5; c < all[k].cols; ++c) {
        EXPECT_LE(a[c], a[4] + 1e-6f);
        if (a[4] < 0.5f) {
          EXPECT_EQ(b[c], 0.0f);
          ++zeroed;
        } else {
          EXPECT_FLOAT_EQ(a[c], b[c]);
          ++kept;
        }
      }
    }
  }
  EXPECT_GT(zeroed, 0);
  EXPECT_GT(kept, 0);
}

TEST(DarknetOneDnn, InputScaleAndSwapAreFoldedExactly) {
  const SmallNet n = small_net("darknet_fold");
  DarknetOneDnn plain(n.cfg.string(), n.weights.string(), 64, 64);
  DarknetOneDnnOptions o;
  o.input_scale = 1.0f / 255.0f;
  o.swap_rb = true;
  DarknetOneDnn folded(n.cfg.string(), n.weights.string(), 64, 64, o);
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> px(0, 255);
  for (int i = 0; i < 64 * 64; ++i) {
    const int b = px(rng), g = px(rng), r = px(rng);
    folded.input()[3 * i + 0] = static_cast<float>(b);
    folded.input()[3 * i + 1] = static_cast<float>(g);
    folded.input()[3 * i + 2] = static_cast<float>(r);
    plain.input()[3 * i + 0] = static_cast<float>(r) / 255.0f;
    plain.input()[3 * i + 1] = static_cast<float>(g) / 255.0f;
    plain.input()[3 * i + 2] = static_cast<float>(b) / 255.0f;
  }
  const auto& a = plain.forward(0.0f);
  const auto& b = folded.forward(0.0f);
  double worst = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    for (std::size_t j = 0; j < a[k].data.size(); ++j) {
      worst = std::max(worst, std::abs(double(a[k].data[j]) - b[k].data[j]));
    }
  }
  EXPECT_LT(worst, 1e-4);
  EXPECT_GT(a.front().data.size(), 0u);
}

// ---- errors ----------------------------------------------------------------------------------

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

// The 1-based line of the first `needle` in `text`.
int line_of(const std::string& text, const std::string& needle) {
  const auto at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}
std::string at_line(const SmallNet& n, const std::string& needle) {
  return n.cfg.string() + ":" + std::to_string(line_of(kSmallCfg, needle)) + ":";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(DarknetOneDnn, ErrorsNameTheFileLineAndKey) {
  {  // a layer kind it does not run, with its cfg line
    const SmallNet n = small_net("darknet_err_kind", replaced(kSmallCfg, "[dropout]", "[gru]"));
    const std::string e =
        error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 64, 64); });
    EXPECT_NE(e.find(at_line(n, "[dropout]")), std::string::npos) << e;
    EXPECT_NE(e.find("[gru]"), std::string::npos) << e;
  }
  {  // an activation it does not run
    const SmallNet n =
        small_net("darknet_err_act", replaced(kSmallCfg, "activation=leaky", "activation=mish"));
    const std::string e =
        error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 64, 64); });
    EXPECT_NE(e.find(at_line(n, "activation=leaky")), std::string::npos) << e;
    EXPECT_NE(e.find("'activation'"), std::string::npos) << e;
    EXPECT_NE(e.find("mish"), std::string::npos) << e;
  }
  {  // not a number
    const SmallNet n = small_net("darknet_err_int", replaced(kSmallCfg, "filters=8", "filters=8x"));
    const std::string e =
        error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 64, 64); });
    EXPECT_NE(e.find(at_line(n, "filters=8")), std::string::npos) << e;
    EXPECT_NE(e.find("'filters'"), std::string::npos) << e;
  }
  {  // a route past the start of the network
    const SmallNet n =
        small_net("darknet_err_route", replaced(kSmallCfg, "layers=-1,-2", "layers=-1,-20"));
    const std::string e =
        error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 64, 64); });
    EXPECT_NE(e.find("'layers'"), std::string::npos) << e;
    EXPECT_NE(e.find("out of range"), std::string::npos) << e;
  }
  {  // groups that do not divide the channels
    const SmallNet n = small_net("darknet_err_groups", replaced(kSmallCfg, "groups=2", "groups=3"));
    const std::string e =
        error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 64, 64); });
    EXPECT_NE(e.find("'groups'"), std::string::npos) << e;
  }
  {  // weights too short and too long for the cfg
    const SmallNet shorter = small_net("darknet_err_short", kSmallCfg, 0, 3);
    std::string e =
        error_of([&] { DarknetOneDnn(shorter.cfg.string(), shorter.weights.string(), 64, 64); });
    EXPECT_NE(e.find(shorter.weights.string()), std::string::npos) << e;
    EXPECT_NE(e.find("ends early"), std::string::npos) << e;
    EXPECT_NE(e.find("layer 16"), std::string::npos) << e;
    const SmallNet longer = small_net("darknet_err_long", kSmallCfg, 5, 0);
    e = error_of([&] { DarknetOneDnn(longer.cfg.string(), longer.weights.string(), 64, 64); });
    EXPECT_NE(e.find(longer.weights.string()), std::string::npos) << e;
    EXPECT_NE(e.find("20 bytes more"), std::string::npos) << e;
  }
  {  // missing files, input size, options
    const SmallNet n = small_net("darknet_err_misc");
    std::string e =
        error_of([&] { DarknetOneDnn("/nonexistent/x.cfg", n.weights.string(), 64, 64); });
    EXPECT_NE(e.find("/nonexistent/x.cfg"), std::string::npos) << e;
    e = error_of([&] { DarknetOneDnn(n.cfg.string(), "/nonexistent/x.weights", 64, 64); });
    EXPECT_NE(e.find("/nonexistent/x.weights"), std::string::npos) << e;
    e = error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 60, 64); });
    EXPECT_NE(e.find("multiple of 32"), std::string::npos) << e;
    DarknetOneDnnOptions o;
    o.threads = -1;
    e = error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 64, 64, o); });
    EXPECT_NE(e.find("'threads'"), std::string::npos) << e;
    o = {};
    o.input_scale = 0.0f;
    e = error_of([&] { DarknetOneDnn(n.cfg.string(), n.weights.string(), 64, 64, o); });
    EXPECT_NE(e.find("'input_scale'"), std::string::npos) << e;
  }
}

// ---- the two YoloFastest backends on the real images -----------------------------------------

TEST(YoloFastestBackends, OneDnnGivesOpenCvsBoxes) {
  EXPECT_TRUE(parse_yolo_backend("onednn") == YoloBackend::kOneDnn);
  EXPECT_TRUE(parse_yolo_backend("opencv") == YoloBackend::kOpenCv);
  EXPECT_FALSE(parse_yolo_backend("ncnn").has_value());
  EXPECT_EQ(to_string(YoloBackend::kOneDnn), "onednn");
  EXPECT_EQ(YoloFastestOptions{}.backend, YoloBackend::kOneDnn);

  YoloFastestOptions o;
  o.backend = YoloBackend::kOpenCv;
  YoloFastest opencv(models_dir(), o);
  o.backend = YoloBackend::kOneDnn;
  YoloFastest onednn(models_dir(), o);
  std::vector<Image> images;
  for (const std::string& rel : kImages) {
    images.push_back(io::load_image(test::shared_data(rel).string(), io::ImageKind::kColor));
  }
  cv::VideoCapture cap(test::shared_data("video/vtest.avi").string());
  cv::Mat frame;
  for (int i = 0; i < 10 && cap.read(frame); ++i) images.push_back(io::to_image(frame.clone()));
  ASSERT_EQ(images.size(), kImages.size() + 10);

  // Recall of OpenCV's boxes and the IoU of the matches; boxes within 0.01 of the threshold
  // may fall on either side of it.
  int reference = 0, matched = 0, extra = 0;
  double iou_sum = 0, worst_iou = 1, worst_score = 0;
  for (const Image& image : images) {
    const DetectionSet a = opencv.detect(image, 0);
    const DetectionSet b = onednn.detect(image, 0);
    for (const Detection& p : a.boxes) {
      if (p.score < o.conf_threshold + 0.01f) continue;
      ++reference;
      const Detection* best = nullptr;
      for (const Detection& q : b.boxes) {
        if (q.label == p.label && (!best || iou(p, q) > iou(p, *best))) best = &q;
      }
      if (!best || iou(p, *best) < 0.9f) continue;
      ++matched;
      iou_sum += iou(p, *best);
      worst_iou = std::min(worst_iou, static_cast<double>(iou(p, *best)));
      worst_score = std::max(worst_score, static_cast<double>(std::abs(p.score - best->score)));
    }
    for (const Detection& q : b.boxes) {
      if (q.score < o.conf_threshold + 0.01f) continue;
      const bool found = std::any_of(a.boxes.begin(), a.boxes.end(), [&](const Detection& p) {
        return p.label == q.label && iou(p, q) >= 0.9f;
      });
      extra += !found;
    }
  }
  std::cout << "oneDNN vs OpenCV on " << images.size() << " images: recall " << matched << "/"
            << reference << ", mean IoU " << (matched ? iou_sum / matched : 0) << ", worst IoU "
            << worst_iou << ", worst score difference " << worst_score << ", boxes OpenCV lacks "
            << extra << "\n";
  EXPECT_GE(reference, 60);
  EXPECT_EQ(matched, reference);
  EXPECT_EQ(extra, 0);
  EXPECT_GT(worst_iou, 0.98);
  EXPECT_LT(worst_score, 0.01);
}

}  // namespace
}  // namespace kestrel::detect

// ---- int8 ------------------------------------------------------------------------------------

namespace kestrel::detect {
namespace {

std::vector<Image> calibration_images() {
  return int8_calibration_images(test::shared_dir().append("data").string());
}

struct Agreement {
  int reference = 0, matched = 0, extra = 0;
  double iou_sum = 0, worst_iou = 1, worst_score = 0;
};

// Recall of `a`'s boxes (score at least 0.05 above the threshold) among `b`'s of the same label
// with IoU >= 0.7, and `b`'s confident boxes that `a` lacks.
Agreement agreement(YoloFastest& a, YoloFastest& b, const std::vector<Image>& images) {
  Agreement g;
  const float sure = a.options().conf_threshold + 0.05f;
  for (const Image& image : images) {
    const DetectionSet x = a.detect(image, 0);
    const DetectionSet y = b.detect(image, 0);
    for (const Detection& p : x.boxes) {
      if (p.score < sure) continue;
      ++g.reference;
      const Detection* best = nullptr;
      for (const Detection& q : y.boxes) {
        if (q.label == p.label && (!best || iou(p, q) > iou(p, *best))) best = &q;
      }
      if (!best || iou(p, *best) < 0.7f) continue;
      ++g.matched;
      g.iou_sum += iou(p, *best);
      g.worst_iou = std::min(g.worst_iou, static_cast<double>(iou(p, *best)));
      g.worst_score = std::max(g.worst_score, static_cast<double>(std::abs(p.score - best->score)));
    }
    for (const Detection& q : y.boxes) {
      if (q.score < sure) continue;
      g.extra += std::none_of(x.boxes.begin(), x.boxes.end(), [&](const Detection& p) {
        return p.label == q.label && iou(p, q) >= 0.7f;
      });
    }
  }
  return g;
}

TEST(YoloFastestInt8, KeepsTheFp32BoxesOnTheTestImages) {
  YoloFastest fp32(models_dir());
  YoloFastestOptions o;
  o.precision = YoloPrecision::kInt8;
  o.int8_calibration = calibration_images();
  ASSERT_EQ(o.int8_calibration.size(), 12u);
  YoloFastest int8(models_dir(), o);
  EXPECT_TRUE(int8.options().int8_calibration.empty());  // released after calibration

  std::vector<Image> images;
  for (const std::string& rel : kImages) {
    images.push_back(io::load_image(test::shared_data(rel).string(), io::ImageKind::kColor));
  }
  cv::VideoCapture cap(test::shared_data("video/vtest.avi").string());
  cv::Mat frame;
  for (int i = 0; i < 20 && cap.read(frame); ++i) images.push_back(io::to_image(frame.clone()));
  const Agreement g = agreement(fp32, int8, images);
  std::cout << "int8 vs fp32 on " << images.size() << " images: recall " << g.matched << "/"
            << g.reference << ", mean IoU " << (g.matched ? g.iou_sum / g.matched : 0)
            << ", worst IoU " << g.worst_iou << ", worst score difference " << g.worst_score
            << ", confident boxes fp32 lacks " << g.extra << "\n";
  EXPECT_GE(g.reference, 80);
  EXPECT_GE(g.matched, g.reference * 95 / 100);
  EXPECT_GT(g.iou_sum / std::max(1, g.matched), 0.9);
  EXPECT_LE(g.extra, g.reference / 20);
}

TEST(DarknetOneDnnInt8, RowsStayCloseToFp32) {
  const YoloModelFiles f = yolo_model_files(models_dir(), YoloModel::kV11);
  DarknetOneDnn fp32(f.cfg, f.weights, 320, 320);
  DarknetOneDnn int8(f.cfg, f.weights, 320, 320);
  const std::vector<Image> calib = calibration_images();
  auto fill = [](const Image& image, float* in) {
    cv::Mat bgr = io::as_mat(image);
    if (image.channels == 1) cv::cvtColor(bgr, bgr, cv::COLOR_GRAY2BGR);
    fill_nhwc(
        cv::dnn::blobFromImage(bgr, 1.0 / 255.0, cv::Size(320, 320), cv::Scalar(), true, false),
        in);
  };
  EXPECT_FALSE(int8.int8());
  int8.quantize_int8([&](std::size_t i, float* in) { fill(calib[i], in); }, calib.size());
  EXPECT_TRUE(int8.int8());
  EXPECT_NE(error_of([&] { int8.quantize_int8([&](std::size_t, float*) {}, 1); }).find("already"),
            std::string::npos);
  EXPECT_NE(
      error_of([&] { fp32.quantize_int8([&](std::size_t, float*) {}, 0); }).find("calibration"),
      std::string::npos);
  // On the test images: the confident rows' best class score moves by little on average.
  double sum = 0, worst = 0, any = 0;
  int n = 0;
  for (const std::string& rel : kImages) {
    const cv::Mat blob = blob_of(rel, 320);
    fill_nhwc(blob, fp32.input());
    fill_nhwc(blob, int8.input());
    const std::vector<YoloHeadRows> a = fp32.forward(0.0f);
    const std::vector<YoloHeadRows>& b = int8.forward(0.0f);
    for (std::size_t k = 0; k < a.size(); ++k) {
      for (int r = 0; r < a[k].rows; ++r) {
        const float* x = a[k].row(r);
        const float* y = b[k].row(r);
        any = std::max(any, std::abs(double(x[4]) - y[4]));
        const int c = static_cast<int>(std::max_element(x + 5, x + a[k].cols) - x);
        if (x[c] < 0.25f) continue;
        const double d = std::abs(double(x[c]) - y[c]);
        sum += d;
        worst = std::max(worst, d);
        ++n;
      }
    }
  }
  std::cout << "int8 vs fp32 rows: " << n << " confident rows, mean |score change| " << sum / n
            << ", worst " << worst << "\n";
  EXPECT_GT(any, 1e-3);  // int8 really runs
  EXPECT_GE(n, 50);
  EXPECT_LT(sum / n, 0.06);
  EXPECT_LT(worst, 0.35);
}

// The facts YoloFastestTest checks for fp32 that int8 keeps: the TUM frame's two people and
// their mask coverage, and the sample photos' classes.
TEST(YoloFastestInt8, TumFrameAndPhotos) {
  YoloFastestOptions o;
  o.precision = YoloPrecision::kInt8;
  o.int8_calibration = calibration_images();
  YoloFastest int8(models_dir(), o);
  const Image rgb = io::load_image(test::shared_data(kImages[0]).string(), io::ImageKind::kColor);
  const Image mask =
      io::load_image(test::shared_data("tum_fr3/frame/static_mask_1341846313.592026.png").string(),
                     io::ImageKind::kGrey);
  const DetectionSet set = int8.detect(rgb, 0);
  long total = 0, covered = 0;
  for (int y = 0; y < mask.height; ++y) {
    for (int x = 0; x < mask.width; ++x) {
      if (mask.row<std::uint8_t>(y)[x] != 0) continue;
      ++total;
      covered += std::any_of(set.boxes.begin(), set.boxes.end(), [&](const Detection& d) {
        return d.label == "person" && x + 0.5 >= d.x_min && x + 0.5 < d.x_max &&
               y + 0.5 >= d.y_min && y + 0.5 < d.y_max;
      });
    }
  }
  const double coverage = static_cast<double>(covered) / static_cast<double>(total);
  std::cout << "int8 person-mask coverage v1.1@320: " << coverage << "\n";
  EXPECT_GE(coverage, 0.90);
  EXPECT_EQ(std::count_if(set.boxes.begin(), set.boxes.end(),
                          [](const Detection& d) { return d.label == "person"; }),
            2);
  auto labels = [&](const std::string& rel) {
    std::map<std::string, float> best;
    for (const Detection& d :
         int8.detect(io::load_image(test::shared_data(rel).string(), io::ImageKind::kColor), 0)
             .boxes) {
      best[d.label] = std::max(best[d.label], d.score);
    }
    return best;
  };
  auto person = labels("images/person.jpg");
  EXPECT_GT(person["person"], 0.9f);
  EXPECT_GT(person["dog"], 0.5f);
  auto dog = labels("images/dog.jpg");
  EXPECT_GT(dog["dog"], 0.5f);
  EXPECT_TRUE(dog.contains("bicycle"));
  EXPECT_TRUE(dog.contains("car") || dog.contains("truck"));
  EXPECT_TRUE(labels("images/horses.jpg").contains("horse"));
  EXPECT_EQ(labels("images/000004.jpg").count("car"), 1u);
  EXPECT_GT(labels("images/000230.jpg")["person"], 0.9f);
}

TEST(YoloFastestInt8, OptionsAreChecked) {
  YoloFastestOptions o;
  o.precision = YoloPrecision::kInt8;
  std::string e = error_of([&] { YoloFastest(models_dir(), o); });
  EXPECT_NE(e.find("'int8_calibration'"), std::string::npos) << e;
  o.int8_calibration.push_back(Image{});
  e = error_of([&] { YoloFastest(models_dir(), o); });
  EXPECT_NE(e.find("'int8_calibration'"), std::string::npos) << e;
  o.int8_calibration = {Image::allocate(8, 8, 3, PixelType::kU8)};
  o.backend = YoloBackend::kOpenCv;
  e = error_of([&] { YoloFastest(models_dir(), o); });
  EXPECT_NE(e.find("'precision'"), std::string::npos) << e;
}

}  // namespace
}  // namespace kestrel::detect
