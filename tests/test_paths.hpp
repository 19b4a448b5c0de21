#pragma once
// Where tests find the shared reference data and the built CLI.
#include <cstdlib>
#include <filesystem>
#include <string>

namespace kestrel::test {

// $KESTREL_SHARED, else ../shared beside the source tree (DESIGN.md).
inline std::filesystem::path shared_dir() {
  if (const char* env = std::getenv("KESTREL_SHARED"); env && *env) return env;
  return std::filesystem::path(KESTREL_SOURCE_DIR) / ".." / "shared";
}
inline std::filesystem::path shared_data(const std::string& rel) {
  return shared_dir() / "data" / rel;
}
inline std::filesystem::path build_dir() {
  if (const char* env = std::getenv("KESTREL_BUILD_DIR"); env && *env) return env;
  return std::filesystem::path(KESTREL_SOURCE_DIR) / "build";
}
// A fresh empty directory under the system temp dir, unique per test.
std::filesystem::path temp_dir(const std::string& name);

}  // namespace kestrel::test
