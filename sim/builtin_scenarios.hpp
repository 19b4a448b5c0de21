#pragma once
// The scenario files of config/scenarios/, compiled into the binary so that
// `kestrel sim --scenario cafe` works from any directory.
#include <string>
#include <vector>

namespace kestrel::sim {

// YAML text of the built-in NAME, or nullptr.
const char* builtin_scenario(const std::string& name);
std::vector<std::string> builtin_scenario_names();

}  // namespace kestrel::sim
