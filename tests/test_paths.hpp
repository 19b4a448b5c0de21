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
// Factor on the time limits of tests that wait on whole processes: $KESTREL_TEST_TIME_SCALE,
// set by CTest in the sanitizer builds (cmake/KestrelOptions.cmake), else 1.
inline int time_scale() {
  const char* env = std::getenv("KESTREL_TEST_TIME_SCALE");
  const int s = env ? std::atoi(env) : 1;
  return s >= 1 ? s : 1;
}
// A fresh empty directory under the system temp dir, unique per test; removed when the process
// exits unless a test failed or KESTREL_KEEP_TEST_DIRS is set.
std::filesystem::path temp_dir(const std::string& name);

}  // namespace kestrel::test
