#pragma once
// A minimal owned image so that core types stay free of OpenCV (DESIGN.md: core headers include
// only the standard library and Eigen). io/cv_image.hpp wraps it as a cv::Mat without copying.
#include <cstdint>
#include <memory>
#include <vector>

namespace kestrel {

enum class PixelType : std::uint8_t { kU8, kU16 };

struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  PixelType type = PixelType::kU8;
  // Shared so that frames can be passed between pipeline stages without copying pixels.
  std::shared_ptr<std::vector<std::uint8_t>> data;

  static Image allocate(int width, int height, int channels, PixelType type) {
    Image im;
    im.width = width;
    im.height = height;
    im.channels = channels;
    im.type = type;
    im.data = std::make_shared<std::vector<std::uint8_t>>(
        static_cast<std::size_t>(width) * height * channels * (type == PixelType::kU16 ? 2 : 1));
    return im;
  }

  bool empty() const { return !data || width == 0 || height == 0; }
  int bytes_per_pixel() const { return channels * (type == PixelType::kU16 ? 2 : 1); }
  std::size_t step() const { return static_cast<std::size_t>(width) * bytes_per_pixel(); }

  template <typename T>
  T* row(int y) {
    return reinterpret_cast<T*>(data->data() + static_cast<std::size_t>(y) * step());
  }
  template <typename T>
  const T* row(int y) const {
    return reinterpret_cast<const T*>(data->data() + static_cast<std::size_t>(y) * step());
  }
};

}  // namespace kestrel
