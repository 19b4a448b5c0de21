#include "pipeline/mover_mask.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>

#include "io/cv_image.hpp"

namespace kestrel::pipeline {

Image mover_mask(int width, int height, const std::vector<dynamic::BoxRegion>& boxes, int margin) {
  Image mask = Image::allocate(width, height, 1, PixelType::kU8);
  cv::Mat m = io::as_mat(mask);
  m.setTo(0);
  for (const auto& b : boxes) {
    if (b.parked) continue;
    const int x0 = std::clamp(static_cast<int>(std::floor(b.x_min)) - margin, 0, width);
    const int y0 = std::clamp(static_cast<int>(std::floor(b.y_min)) - margin, 0, height);
    const int x1 = std::clamp(static_cast<int>(std::ceil(b.x_max)) + margin, 0, width);
    const int y1 = std::clamp(static_cast<int>(std::ceil(b.y_max)) + margin, 0, height);
    if (x1 > x0 && y1 > y0) m(cv::Rect(x0, y0, x1 - x0, y1 - y0)).setTo(255);
  }
  return mask;
}

LastMoverMasks last_mover_masks(const std::vector<dynamic::BoxRegion>& boxes,
                                const Image& last_depth, double last_depth_scale, int width,
                                int height, int budget_margin_px, bool silhouettes,
                                const dynamic::MoverSilhouetteOptions& opt,
                                const dynamic::DynamicFilterOptions& filter) {
  LastMoverMasks out;
  if (boxes.empty()) return out;
  if (budget_margin_px >= 0) out.movers = mover_mask(width, height, boxes, budget_margin_px);
  if (silhouettes && !last_depth.empty() && last_depth.width == width &&
      last_depth.height == height) {
    out.silhouette = dynamic::mover_silhouette(last_depth, last_depth_scale, boxes, opt, filter);
  }
  return out;
}

}  // namespace kestrel::pipeline
