# cmake -DOUT=file.cpp -DFILES="a.yaml|b.yaml" -P embed_scenarios.cmake
# Writes the built-in scenario table (sim/builtin_scenarios.hpp) with each file as a raw string.
string(REPLACE "|" ";" FILES "${FILES}")
set(entries "")
foreach(f IN LISTS FILES)
  get_filename_component(name ${f} NAME_WE)
  file(READ ${f} text)
  string(APPEND entries "    {\"${name}\", R\"KESTREL_YAML(${text})KESTREL_YAML\"},\n")
endforeach()
set(content "// Generated from config/scenarios/*.yaml by sim/embed_scenarios.cmake. Do not edit.
#include <utility>

namespace kestrel::sim {
extern const std::pair<const char*, const char*> kBuiltinScenarios[];
extern const int kBuiltinScenarioCount;
const std::pair<const char*, const char*> kBuiltinScenarios[] = {
${entries}    {nullptr, nullptr}};
const int kBuiltinScenarioCount = static_cast<int>(sizeof(kBuiltinScenarios) / sizeof(kBuiltinScenarios[0])) - 1;
}  // namespace kestrel::sim
")
file(WRITE ${OUT}.tmp "${content}")
file(COPY_FILE ${OUT}.tmp ${OUT} ONLY_IF_DIFFERENT)
