#include "detect/letterbox.hpp"

#include <stdexcept>

namespace kestrel::detect {

Letterbox Letterbox::make(int image_width, int image_height, int net_width, int net_height,
                          InputResize mode) {
  if (image_width <= 0 || image_height <= 0 || net_width <= 0 || net_height <= 0) {
    throw std::invalid_argument("Letterbox::make: sizes must be positive");
  }
  Letterbox lb;
  lb.image_width = image_width;
  lb.image_height = image_height;
  lb.net_width = net_width;
  lb.net_height = net_height;
  if (mode == InputResize::kStretch) {
    lb.resized_width = net_width;
    lb.resized_height = net_height;
    return lb;
  }
  // Darknet compares the float ratios and then divides in integers; the same here, so that a
  // box maps exactly as in Darknet's correct_yolo_boxes().
  const long long iw = image_width, ih = image_height;
  if (static_cast<double>(net_width) / image_width <
      static_cast<double>(net_height) / image_height) {
    lb.resized_width = net_width;
    lb.resized_height = static_cast<int>(ih * net_width / iw);
  } else {
    lb.resized_height = net_height;
    lb.resized_width = static_cast<int>(iw * net_height / ih);
  }
  // A sliver image (e.g. 1000x1) would round to zero rows.
  if (lb.resized_width < 1) lb.resized_width = 1;
  if (lb.resized_height < 1) lb.resized_height = 1;
  lb.pad_x = (net_width - lb.resized_width) / 2;
  lb.pad_y = (net_height - lb.resized_height) / 2;
  return lb;
}

}  // namespace kestrel::detect
