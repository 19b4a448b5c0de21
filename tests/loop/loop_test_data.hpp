#pragma once
// Descriptors for the loop tests: ORB features of the shared reference images and of
// simulator frames.
#include <string>
#include <vector>

#include "core/camera.hpp"
#include "io/image_io.hpp"
#include "tests/test_paths.hpp"
#include "tracking/feature_extractor.hpp"

namespace kestrel::loop::test_data {

inline std::vector<tracking::OrbDescriptor> image_descriptors(const std::string& rel) {
  const Image image =
      io::load_image(kestrel::test::shared_data(rel).string(), io::ImageKind::kColor);
  PinholeCamera camera;
  camera.fx = camera.fy = 500.0;
  camera.cx = image.width / 2.0;
  camera.cy = image.height / 2.0;
  camera.width = image.width;
  camera.height = image.height;
  const tracking::FeatureExtractor extractor(camera);
  return extractor.extract(image).descriptors;
}

inline const std::vector<std::string>& training_images() {
  static const std::vector<std::string> names = {"images/000004.jpg", "images/000139.jpg",
                                                 "images/dog.jpg", "images/horses.jpg",
                                                 "tum_fr3/frame/rgb_1341846313.592026.png"};
  return names;
}

}  // namespace kestrel::loop::test_data
