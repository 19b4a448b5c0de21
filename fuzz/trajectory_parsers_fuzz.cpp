// Arbitrary bytes into the text table and every trajectory parser: each must either parse or
// throw kestrel::Error — never crash, hang or read out of bounds. What parses as TUM must
// survive a write/read round trip.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.hpp"
#include "io/text_lines.hpp"
#include "io/trajectory_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace kestrel;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)io::TextTable::parse(text, "fuzz");
  } catch (const Error&) {
  }
  for (const auto format :
       {io::TrajectoryFormat::kTum, io::TrajectoryFormat::kEuroc, io::TrajectoryFormat::kKitti}) {
    try {
      (void)io::parse_pose_series(text, "fuzz", format);
    } catch (const Error&) {
    }
  }
  Trajectory trajectory;
  try {
    trajectory = io::parse_trajectory(text, "fuzz");
  } catch (const Error&) {
    return 0;
  }
  const Trajectory again = io::parse_trajectory(io::format_tum(trajectory), "fuzz-round-trip");
  if (again.size() != trajectory.size()) __builtin_trap();
  for (std::size_t i = 0; i < again.size(); ++i) {
    if (again.stamps[i] != trajectory.stamps[i]) __builtin_trap();
  }
  return 0;
}
