#pragma once
// The ROS map_server pair: map.yaml (image, resolution, origin, negate, occupied_thresh,
// free_thresh) and the image it names, here a binary PGM (P5). Errors name file, line, field.
#include <string>

#include "maps/occupancy_grid.hpp"

namespace kestrel::maps {

struct MapMetadata {
  std::string image;  // path as written in the YAML (relative to the YAML's folder)
  double resolution = 0.05;
  double origin_x = 0.0;
  double origin_y = 0.0;
  double origin_yaw = 0.0;  // accepted when 0 only: a rotated grid is not supported
  bool negate = false;
  double occupied_thresh = 0.65;
  double free_thresh = 0.196;
};

// Reads map.yaml and its image (P5 PGM, 8-bit; P2 ASCII PGM accepted too).
OccupancyGrid read_map(const std::string& yaml_path);
MapMetadata read_map_metadata(const std::string& yaml_path);
// Writes yaml_path and, beside it, <stem>.pgm with map_saver's trinary values
// (occupied 0, free 254, unknown 205).
void write_map(const std::string& yaml_path, const OccupancyGrid& grid);

}  // namespace kestrel::maps
