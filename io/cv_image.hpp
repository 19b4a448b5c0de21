#pragma once
// Image <-> cv::Mat. Include only in .cpp files: it pulls in OpenCV.
#include <cstring>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "core/image.hpp"

namespace kestrel::io {

inline int cv_type_of(const Image& im) {
  return CV_MAKETYPE(im.type == PixelType::kU16 ? CV_16U : CV_8U, im.channels);
}

// A cv::Mat header over the Image's pixels: no copy. Writing through the Mat writes the Image
// (the pixels are shared, as Image's own copies share them). An empty Image gives an empty Mat.
inline cv::Mat as_mat(const Image& im) {
  if (im.empty()) return cv::Mat();
  return cv::Mat(im.height, im.width, cv_type_of(im), const_cast<std::uint8_t*>(im.data->data()),
                 im.step());
}

// Copies a cv::Mat (8- or 16-bit unsigned, 1 to 4 channels) into a new Image.
inline Image to_image(const cv::Mat& m) {
  if (m.empty()) return Image{};
  PixelType type;
  if (m.depth() == CV_8U) {
    type = PixelType::kU8;
  } else if (m.depth() == CV_16U) {
    type = PixelType::kU16;
  } else {
    throw std::invalid_argument("to_image: only 8- and 16-bit unsigned images are supported");
  }
  Image im = Image::allocate(m.cols, m.rows, m.channels(), type);
  const std::size_t row_bytes = im.step();
  for (int y = 0; y < m.rows; ++y) std::memcpy(im.row<std::uint8_t>(y), m.ptr(y), row_bytes);
  return im;
}

}  // namespace kestrel::io
