#include "sim/builtin_scenarios.hpp"

#include <utility>

namespace kestrel::sim {

extern const std::pair<const char*, const char*> kBuiltinScenarios[];
extern const int kBuiltinScenarioCount;

const char* builtin_scenario(const std::string& name) {
  for (int i = 0; i < kBuiltinScenarioCount; ++i) {
    if (name == kBuiltinScenarios[i].first) return kBuiltinScenarios[i].second;
  }
  return nullptr;
}

std::vector<std::string> builtin_scenario_names() {
  std::vector<std::string> names;
  for (int i = 0; i < kBuiltinScenarioCount; ++i) names.emplace_back(kBuiltinScenarios[i].first);
  return names;
}

}  // namespace kestrel::sim
