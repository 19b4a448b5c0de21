#pragma once
// Cut-outs of people and vehicles from the real photographs in the shared data folder
// (images/), so that the real detector recognises the simulated movers. The photos have no
// masks: each cut-out is named in a small table (photo_cutouts.cpp) by its photo, a rectangle
// around the subject and optional hint rectangles, and OpenCV's grabCut separates subject and
// background at load time. Nothing is copied into the repository.
#include <array>
#include <string>
#include <vector>

#include "sim/texture.hpp"

namespace kestrel::sim {

struct Cutout {
  Texture texture;      // RGBA, alpha marks the subject; u runs left to right, v top to bottom
  double aspect = 1.0;  // width / height of the subject's bounding box in the photo
  // Vehicles: the silhouette's top and bottom edge per column (fractions of the height from
  // the top, 0 = top of the bounding box), `columns` samples from left to right; empty for
  // people. They shape the vehicle's body so that its outline matches the photo.
  std::vector<float> top, bottom;
  bool front_left = true;  // vehicles: the front of the car is at the left of the photo
  std::array<int, 3> paint{128, 128, 128};  // RGB: the subject's typical body colour
};

// Names in the table: people first (person-*), then vehicle sides (car-*).
const std::vector<std::string>& cutout_names();

// Cuts `name` from its photo under assets_dir/images. columns: silhouette samples (vehicles).
// Throws kestrel::Error naming the file when the photo is missing or unreadable, or naming
// the cut-out when it is not in the table.
Cutout load_cutout(const std::string& assets_dir, const std::string& name, bool mirror = false,
                   int columns = 0);

}  // namespace kestrel::sim
