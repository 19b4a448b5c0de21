#include "dynamic/mover_silhouette.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "dynamic/object_depth.hpp"

namespace kestrel::dynamic {

void validate(const MoverSilhouetteOptions& opt, const DynamicFilterOptions& filter) {
  if (opt.grow_px < 0) {
    throw std::invalid_argument("MoverSilhouetteOptions::grow_px must be >= 0, got " +
                                std::to_string(opt.grow_px));
  }
  if (opt.min_readings < 1) {
    throw std::invalid_argument("MoverSilhouetteOptions::min_readings must be >= 1, got " +
                                std::to_string(opt.min_readings));
  }
  if (!(filter.foreground_band_m > 0.0) || !(filter.foreground_band_rel >= 0.0)) {
    throw std::invalid_argument(
        "mover_silhouette: DynamicFilterOptions::foreground_band_m must be > 0 and "
        "foreground_band_rel >= 0");
  }
}

Image mover_silhouette(const Image& depth, double depth_scale, const std::vector<BoxRegion>& boxes,
                       const MoverSilhouetteOptions& opt, const DynamicFilterOptions& filter) {
  if (depth.empty() || depth.type != PixelType::kU16 || depth.channels != 1) {
    throw std::invalid_argument("mover_silhouette: depth must be a 16-bit, 1-channel image");
  }
  if (!(depth_scale > 0.0)) {
    throw std::invalid_argument("mover_silhouette: depth_scale must be positive");
  }
  validate(opt, filter);
  const int w = depth.width, h = depth.height;
  Image out = Image::allocate(w, h, 1, PixelType::kU8);
  cv::Mat mask(h, w, CV_8U, out.data->data());
  mask.setTo(0);
  bool any = false;
  for (const BoxRegion& box : boxes) {
    if (box.parked) continue;
    const std::vector<double> surface = largest_surface(depth, depth_scale, box_core(box), filter);
    if (static_cast<int>(surface.size()) < opt.min_readings) continue;
    const double d = surface[surface.size() / 2];
    const double band = foreground_band(d, filter);
    // The band in raw readings, so the loop compares integers.
    const double lo_m = std::max(0.0, d - band), hi_m = d + band;
    const auto lo = static_cast<std::uint32_t>(std::ceil(lo_m * depth_scale));
    const auto hi = static_cast<std::uint32_t>(std::floor(hi_m * depth_scale));
    const int x0 = std::clamp(static_cast<int>(std::floor(box.x_min)), 0, w);
    const int x1 = std::clamp(static_cast<int>(std::ceil(box.x_max)), 0, w);
    const int y0 = std::clamp(static_cast<int>(std::floor(box.y_min)), 0, h);
    const int y1 = std::clamp(static_cast<int>(std::ceil(box.y_max)), 0, h);
    for (int v = y0; v < y1; ++v) {
      const std::uint16_t* row = depth.row<std::uint16_t>(v);
      std::uint8_t* o = mask.ptr<std::uint8_t>(v);
      for (int u = x0; u < x1; ++u) {
        if (row[u] && row[u] >= lo && row[u] <= hi) o[u] = 255;
      }
    }
    any = true;
  }
  if (any && opt.grow_px > 0) {
    const int k = 2 * opt.grow_px + 1;
    cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  }
  return out;
}

}  // namespace kestrel::dynamic
