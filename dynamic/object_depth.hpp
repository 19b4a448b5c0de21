#pragma once
// A detected object's depth from the depth image under its box: the dynamic filter's test of
// which features lie on the object and the movers' silhouettes (mover_silhouette.hpp) share it.
#include <vector>

#include "core/image.hpp"
#include "dynamic/dynamic_filter.hpp"

namespace kestrel::dynamic {

// The part of a box that is the object's own for sure: the middle half across, from 15% below
// the top to 35% above the bottom (a walker's torso; a car's body above its wheels).
BoxRegion box_core(const BoxRegion& box);

// An object's thickness around its depth: max(foreground_band_m, foreground_band_rel * depth).
double foreground_band(double depth_m, const DynamicFilterOptions& opt);

// The depths (metres, ascending) of the largest surface in `region` of a 16-bit depth image
// (every other pixel): the readings within twice the foreground band of each other that are
// most numerous. A median of all of them would fall between a walker and the wall behind when
// each holds half the region.
std::vector<double> largest_surface(const Image& depth, double scale, const BoxRegion& region,
                                    const DynamicFilterOptions& opt);

}  // namespace kestrel::dynamic
