#include "detect/draw_detections.hpp"

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "detect/dynamic_classes.hpp"
#include "io/cv_image.hpp"

namespace kestrel::detect {

Image draw_detections(const Image& image, const std::vector<Detection>& boxes) {
  if (image.empty()) return Image{};
  if (image.type != PixelType::kU8 || (image.channels != 1 && image.channels != 3)) {
    throw std::invalid_argument("draw_detections: image must be 8-bit BGR or grey");
  }
  cv::Mat canvas;
  if (image.channels == 1) {
    cv::cvtColor(io::as_mat(image), canvas, cv::COLOR_GRAY2BGR);
  } else {
    canvas = io::as_mat(image).clone();
  }
  const int thickness = std::max(1, static_cast<int>(std::lround(canvas.cols / 400.0)));
  for (const Detection& d : boxes) {
    const cv::Scalar colour =
        is_dynamic_class(d.label) ? cv::Scalar(0, 0, 255) : cv::Scalar(0, 200, 0);
    const cv::Point p0(static_cast<int>(std::lround(d.x_min)),
                       static_cast<int>(std::lround(d.y_min)));
    const cv::Point p1(static_cast<int>(std::lround(d.x_max)) - 1,
                       static_cast<int>(std::lround(d.y_max)) - 1);
    cv::rectangle(canvas, p0, p1, colour, thickness);
    char text[96];
    std::snprintf(text, sizeof text, "%s %.2f", d.label.c_str(), static_cast<double>(d.score));
    int baseline = 0;
    const double scale = 0.45 * thickness;
    const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
    const int top = std::max(0, p0.y - size.height - baseline - 2);
    cv::rectangle(canvas, cv::Rect(p0.x, top, size.width + 4, size.height + baseline + 2), colour,
                  cv::FILLED);
    cv::putText(canvas, text, cv::Point(p0.x + 2, top + size.height + 1), cv::FONT_HERSHEY_SIMPLEX,
                scale, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  return io::to_image(canvas);
}

}  // namespace kestrel::detect
