#include "tests/test_paths.hpp"

#include <unistd.h>

#include <cstdlib>
#include <mutex>
#include <system_error>
#include <vector>

#ifdef KESTREL_TEST_GTEST
#include <gtest/gtest.h>
#endif

namespace kestrel::test {
namespace {

// A full ctest run makes about 80 of these (about 1 GB of rendered scenes); left behind they
// fill /tmp after a few runs. They go when the process exits, unless a test failed (what it
// wrote is the evidence) or KESTREL_KEEP_TEST_DIRS is set.
struct Made {
  std::mutex mutex;
  std::vector<std::filesystem::path> dirs;
  pid_t owner = ::getpid();
  bool registered = false;
};

Made& made() {
  static auto* m = new Made;  // never destroyed: the exit handler runs after static destructors
  return *m;
}

bool keep_dirs() {
  if (const char* env = std::getenv("KESTREL_KEEP_TEST_DIRS"); env && *env) return true;
#ifdef KESTREL_TEST_GTEST
  return ::testing::UnitTest::GetInstance()->Failed();
#else
  return false;
#endif
}

void remove_made_dirs() {
  Made& m = made();
  // A forked child that exits normally must not take its parent's directories with it.
  if (::getpid() != m.owner || keep_dirs()) return;
  const std::lock_guard lock(m.mutex);
  for (const auto& dir : m.dirs) {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  m.dirs.clear();
}

}  // namespace

std::filesystem::path temp_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("kestrel-test-" + std::to_string(::getpid()) + "-" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  Made& m = made();
  const std::lock_guard lock(m.mutex);
  if (!m.registered) m.registered = std::atexit(remove_made_dirs) == 0;
  m.dirs.push_back(dir);
  return dir;
}

}  // namespace kestrel::test
