#include "comm/webrtc_frame.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"
#include "io/cv_image.hpp"

namespace kestrel::comm {

std::vector<std::uint8_t> make_i420(const Image& src, int width, int height,
                                    const VideoOverlay* overlay, const FrameStamp& stamp) {
  if (width <= 0 || height <= 0 || width % 2 || height % 2 || width < kStampWidth ||
      height < kStampHeight) {
    throw Error("video frame size " + std::to_string(width) + "x" + std::to_string(height) +
                " must be even and at least the stamp");
  }
  if (src.empty() || src.type != PixelType::kU8 || (src.channels != 1 && src.channels != 3)) {
    throw Error("video frame: need an 8-bit gray or BGR image");
  }
  const cv::Mat in = io::as_mat(src);
  cv::Mat bgr(height, width, CV_8UC3, cv::Scalar(0, 0, 0));
  const double scale =
      std::min(static_cast<double>(width) / src.width, static_cast<double>(height) / src.height);
  const int w = std::max(2, static_cast<int>(src.width * scale + 0.5));
  const int h = std::max(2, static_cast<int>(src.height * scale + 0.5));
  const cv::Rect roi((width - w) / 2, (height - h) / 2, std::min(w, width), std::min(h, height));
  cv::Mat target = bgr(roi);
  cv::Mat color;
  if (in.channels() == 1) {
    cv::cvtColor(in, color, cv::COLOR_GRAY2BGR);
  } else {
    color = in;
  }
  if (roi.width == src.width && roi.height == src.height) {
    color.copyTo(target);
  } else {
    cv::resize(color, target, roi.size(), 0, 0, cv::INTER_LINEAR);
  }
  if (overlay) {
    const auto px = [&](float x, float y) {
      return cv::Point(roi.x + static_cast<int>(x * scale), roi.y + static_cast<int>(y * scale));
    };
    for (const auto& b : overlay->boxes) {
      cv::rectangle(bgr, px(b.x0, b.y0), px(b.x1, b.y1), cv::Scalar(0, 165, 255), 2);
    }
    for (const auto& f : overlay->features) {
      // Static features green, features the dynamic filter rejected red.
      cv::circle(bgr, px(f.x, f.y), 2, f.dynamic ? cv::Scalar(0, 0, 255) : cv::Scalar(0, 220, 0),
                 cv::FILLED);
    }
    if (!overlay->state.empty()) {
      cv::putText(bgr, overlay->state, cv::Point(kStampWidth + 8, 22), cv::FONT_HERSHEY_SIMPLEX,
                  0.6, cv::Scalar(255, 255, 255), 2);
    }
  }
  std::vector<std::uint8_t> out(static_cast<std::size_t>(width) * height * 3 / 2);
  cv::Mat yuv(height * 3 / 2, width, CV_8UC1, out.data());
  cv::cvtColor(bgr, yuv, cv::COLOR_BGR2YUV_I420);
  std::uint8_t* y = out.data();
  std::uint8_t* u = y + static_cast<std::size_t>(width) * height;
  std::uint8_t* v = u + static_cast<std::size_t>(width / 2) * (height / 2);
  stamp_i420(y, width, u, v, width / 2, stamp);
  return out;
}

}  // namespace kestrel::comm
