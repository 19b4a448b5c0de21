#include "loop/place_view.hpp"

#include <utility>

namespace kestrel::loop {

PlaceView place_view(KeyframeId id, const tracking::FrameFeatures& features,
                     std::vector<KeyframeId> neighbours) {
  PlaceView v;
  v.id = id;
  v.neighbours = std::move(neighbours);
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (i < features.status.size() && features.status[i] == tracking::FeatureStatus::kDynamic) {
      continue;
    }
    v.descriptors.push_back(features.descriptors[i]);
    v.points_c.push_back(features.points_c[i]);
    v.keypoints_un.push_back(features.keypoints[i].un);
    v.has_point.push_back(features.has_depth(i) ? 1 : 0);
  }
  return v;
}

}  // namespace kestrel::loop
