// Arbitrary bytes into the configuration reader, in each dialect it accepts (Kestrel YAML,
// ORB-SLAM3 settings, EuRoC sensor.yaml): it must return a calibration or throw kestrel::Error —
// never crash or let a yaml-cpp exception through. What parses must be usable: finite
// intrinsics, and a Kestrel-dialect rewrite that reads back to the same camera.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/config.hpp"
#include "core/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace kestrel;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)detect_dialect(text, "fuzz.yaml");
  } catch (const Error&) {
  }
  Config config;
  try {
    config = parse_config(text, "fuzz.yaml");
  } catch (const Error&) {
    return 0;
  }
  const auto& cam = config.calib.camera;
  if (!std::isfinite(cam.fx) || !std::isfinite(cam.fy) || !std::isfinite(cam.cx) ||
      !std::isfinite(cam.cy)) {
    __builtin_trap();
  }
  const Config again = parse_config(to_yaml(config.calib), "fuzz-round-trip.yaml");
  if (again.calib.camera.width != cam.width || again.calib.camera.height != cam.height) {
    __builtin_trap();
  }
  return 0;
}
