#pragma once
// Person cut-outs from real photographs, so that a real detector recognises the simulated
// walkers: the two people of the TUM fr3 walking frame, cut along its person mask, and their
// mirror images (sprites 0-3), then the people of the photos in images/ cut by grabCut
// (photo_cutouts.hpp), each followed by its mirror image (sprites 4, 5, ...).
#include <string>
#include <vector>

#include "sim/texture.hpp"

namespace kestrel::sim {

struct Sprite {
  Texture texture;      // alpha marks the person
  double aspect = 0.4;  // width / height of the cut-out
};

// Reads tum_fr3/frame/rgb_*.png and static_mask_*.png and the photos under assets_dir. Throws
// kestrel::Error naming the file when one is missing.
std::vector<Sprite> load_person_sprites(const std::string& assets_dir);

}  // namespace kestrel::sim
