// Arbitrary bytes into the map reader (map.bin of an earlier session, loaded for multi-session
// relocalization): it must return a map or throw kestrel::Error naming the part — never crash
// or allocate without bound. What loads must be self-consistent: serializing it again and
// reading that back gives the same bytes.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.hpp"
#include "mapping/map.hpp"
#include "mapping/map_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace kestrel;
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  mapping::Map map;
  try {
    map = mapping::deserialize_map(bytes, "fuzz.bin");
  } catch (const Error&) {
    return 0;
  }
  const std::string again = mapping::serialize_map(map);
  if (mapping::serialize_map(mapping::deserialize_map(again, "fuzz-round-trip.bin")) != again) {
    __builtin_trap();
  }
  return 0;
}

// Seeds for the replay driver: a small map of two keyframes that share a point.
extern "C" void KestrelFuzzSeeds(void (*add)(const std::uint8_t*, std::size_t)) {
  using namespace kestrel;
  tracking::FrameFeatures f;
  f.width = 64;
  f.height = 48;
  for (int i = 0; i < 3; ++i) {
    tracking::Keypoint k;
    k.px = k.un = Vec2(10.0 + 7 * i, 20.0 - 3 * i);
    f.keypoints.push_back(k);
    tracking::OrbDescriptor d;
    d.words[0] = 0x5a5a5a5aULL + static_cast<std::uint64_t>(i);
    f.descriptors.push_back(d);
    f.depth.push_back(1.5 + i);
    f.points_c.push_back(Vec3(0.1 * i, 0.2, 1.5 + i));
    f.status.push_back(tracking::FeatureStatus::kStatic);
  }
  mapping::Map map;
  const auto a = map.add_keyframe(1, SE3(), f);
  const auto b = map.add_keyframe(2, SE3(SO3(), Vec3(0.1, 0, 0)), f);
  const auto p = map.add_point(Vec3(0.1, 0.2, 1.5), a, 0);
  map.add_observation(p, b, 0);
  const std::string bytes = mapping::serialize_map(map);
  add(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  const std::string empty = mapping::serialize_map(mapping::Map());
  add(reinterpret_cast<const std::uint8_t*>(empty.data()), empty.size());
}
