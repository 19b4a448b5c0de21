#include "io/rgbd_list_source.hpp"

#include <filesystem>

#include "core/error.hpp"
#include "io/image_io.hpp"

namespace kestrel::io {

std::string resolve_path(const std::string& dir, const std::string& path) {
  const std::filesystem::path p(path);
  if (p.is_absolute()) return path;
  return (std::filesystem::path(dir) / p).string();
}

std::string folder_name(const std::string& dir) {
  std::error_code ec;
  std::filesystem::path p = std::filesystem::weakly_canonical(std::filesystem::absolute(dir), ec);
  if (ec) p = std::filesystem::path(dir);
  if (p.filename().empty()) p = p.parent_path();
  return p.filename().string();
}

RgbdListSource::RgbdListSource(Contents contents) : contents_(std::move(contents)) {
  std::vector<Timestamp> stamps;
  stamps.reserve(contents_.frames.size());
  for (const RgbdEntry& e : contents_.frames) stamps.push_back(e.t);
  set_streams(std::move(stamps), std::move(contents_.imu));
}

Measurement RgbdListSource::load_frame(std::size_t index) const {
  const RgbdEntry& e = contents_.frames.at(index);
  RgbdFrame f;
  f.t = e.t;
  f.depth_scale = contents_.calib.depth_scale;
  f.source = e.color;
  // The image error names the image; wrap it so the message also names the list line.
  try {
    f.color = load_image(e.color, ImageKind::kColor);
  } catch (const Error& err) {
    throw Error::at(e.color_list, e.color_line, "color", err.what());
  }
  if (!e.depth.empty()) {
    try {
      f.depth = load_image(e.depth, ImageKind::kDepth);
    } catch (const Error& err) {
      throw Error::at(e.depth_list, e.depth_line, "depth", err.what());
    }
    if (f.depth.width != f.color.width || f.depth.height != f.color.height) {
      throw Error::at(e.depth_list, e.depth_line, "depth",
                      e.depth + ": depth is " + std::to_string(f.depth.width) + "x" +
                          std::to_string(f.depth.height) + " but colour " + e.color + " is " +
                          std::to_string(f.color.width) + "x" + std::to_string(f.color.height));
    }
  }
  return f;
}

}  // namespace kestrel::io
