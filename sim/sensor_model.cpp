#include "sim/sensor_model.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "sim/procedural_texture.hpp"

namespace kestrel::sim {
namespace {
constexpr std::size_t kTableBits = 20;
constexpr std::size_t kTableMask = (std::size_t{1} << kTableBits) - 1;
}  // namespace

SensorModel::SensorModel(const SensorSpec& spec, std::uint64_t seed) : spec_(spec), seed_(seed) {
  table_.resize(kTableMask + 1);
  std::mt19937_64 rng(hash_combine(seed, 0x5e5302));
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (float& v : table_) v = n(rng);
}

double SensorModel::exposure_gain(double t) const {
  double g = 1.0;
  for (const auto& step : spec_.exposure)
    if (t >= step[0]) g = step[1];
  return g;
}

double SensorModel::uniform(std::uint64_t key, std::uint64_t index) const {
  return static_cast<double>(hash_combine(hash_combine(seed_, key), index) >> 11) *
         (1.0 / 9007199254740992.0);
}

double SensorModel::gaussian(std::uint64_t key, std::uint64_t index) const {
  return table_[hash_combine(hash_combine(seed_, key), index) & kTableMask];
}

Image SensorModel::color(const std::vector<std::uint8_t>& bgr, int width, int height, double gain,
                         int frame) const {
  Image out = Image::allocate(width, height, 3, PixelType::kU8);
  std::uint8_t* dst = out.data->data();
  const std::size_t n = static_cast<std::size_t>(width) * height * 3;
  const float g = static_cast<float>(gain);
  if (!spec_.noise || spec_.rgb_noise <= 0) {
    for (std::size_t i = 0; i < n; ++i)
      dst[i] = static_cast<std::uint8_t>(std::min(255.0f, bgr[i] * g + 0.5f));
    return out;
  }
  // A contiguous window of the table at a per-frame offset: cheap, and a fresh pattern per frame.
  const std::size_t offset =
      hash_combine(hash_combine(seed_, 0xc01), static_cast<std::uint64_t>(frame)) & kTableMask;
  const float sigma = static_cast<float>(spec_.rgb_noise);
  for (std::size_t i = 0; i < n; ++i) {
    const float v = bgr[i] * g + sigma * table_[(offset + i * 7) & kTableMask] + 0.5f;
    dst[i] = static_cast<std::uint8_t>(std::clamp(v, 0.0f, 255.0f));
  }
  return out;
}

Image SensorModel::depth(const std::vector<float>& inv_depth, int width, int height,
                         double depth_scale, int frame) const {
  Image out = Image::allocate(width, height, 1, PixelType::kU16);
  const float near = static_cast<float>(spec_.depth_min), far = static_cast<float>(spec_.depth_max);
  const float a = spec_.noise ? static_cast<float>(spec_.depth_sigma_z2) : 0.0f;
  const std::size_t offset =
      hash_combine(hash_combine(seed_, 0xde9), static_cast<std::uint64_t>(frame)) & kTableMask;
  const auto z_at = [&](int x, int y) {
    const float w = inv_depth[static_cast<std::size_t>(y) * width + x];
    return w > 0.0f ? 1.0f / w : 0.0f;
  };
  for (int y = 0; y < height; ++y) {
    std::uint16_t* row = out.row<std::uint16_t>(y);
    for (int x = 0; x < width; ++x) {
      const float z = z_at(x, y);
      if (z <= 0.0f) {
        row[x] = 0;
        continue;
      }
      if (spec_.edge_holes > 0.0) {
        // Stereo matching fails at depth discontinuities: a jump of a few per cent to a neighbour.
        const float tol = 0.03f * z + 0.02f;
        bool edge = false;
        if (x > 0) edge |= std::fabs(z_at(x - 1, y) - z) > tol;
        if (x + 1 < width) edge |= std::fabs(z_at(x + 1, y) - z) > tol;
        if (y > 0) edge |= std::fabs(z_at(x, y - 1) - z) > tol;
        if (y + 1 < height) edge |= std::fabs(z_at(x, y + 1) - z) > tol;
        if (edge && uniform(0xed9e + static_cast<std::uint64_t>(frame),
                            static_cast<std::uint64_t>(y) * width + x) < spec_.edge_holes) {
          row[x] = 0;
          continue;
        }
      }
      const std::size_t i = static_cast<std::size_t>(y) * width + x;
      const float zn = z + a * z * z * table_[(offset + i * 5) & kTableMask];
      if (zn < near || zn > far) {
        row[x] = 0;
        continue;
      }
      row[x] = static_cast<std::uint16_t>(std::clamp(std::lround(zn * depth_scale), 1L, 65535L));
    }
  }
  return out;
}

}  // namespace kestrel::sim
