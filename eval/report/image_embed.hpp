#pragma once
// Images as data: URIs, so the report carries its pictures inside the one HTML file.
#include <string>
#include <vector>

#include "core/image.hpp"

namespace kestrel::report {

std::string base64(const std::vector<unsigned char>& bytes);

// "data:image/png;base64,..." (lossless: maps) or "data:image/jpeg;base64,..." (camera frames,
// a tenth of the size). Images wider than max_width are scaled down first (0: never).
// An empty image gives "".
std::string png_data_uri(const Image& image, int max_width = 0);
std::string jpeg_data_uri(const Image& image, int max_width = 0, int quality = 85);

}  // namespace kestrel::report
