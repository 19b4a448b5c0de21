// Arbitrary bytes into the scenario reader (a scenario is user-written YAML, so new worlds need
// no code): it must return a scenario or throw kestrel::Error naming the field — never crash,
// let a yaml-cpp exception through, or accept numbers the simulator cannot use.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.hpp"
#include "sim/scenario.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace kestrel;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const sim::Scenario s = sim::parse_scenario(text, "fuzz.yaml");
    // Negative means "the trajectory's length"; anything else must be a usable number.
    if (!std::isfinite(s.duration)) __builtin_trap();
  } catch (const Error&) {
  }
  return 0;
}
