#pragma once
// Binary little-endian PLY: x y z (float), red green blue (uchar), label (ushort).
#include <string>
#include <vector>

#include "maps/voxel_cloud.hpp"

namespace kestrel::maps {

void write_ply(const std::string& path, const std::vector<CloudPoint>& points);
// Reads what write_ply writes (the same property list); throws kestrel::Error naming the file
// and the header line otherwise.
std::vector<CloudPoint> read_ply(const std::string& path);

}  // namespace kestrel::maps
