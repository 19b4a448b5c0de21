// Background threads step down in priority; the thread that asks is the only one that moves.
#include "pipeline/thread_priority.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <thread>

#if defined(__linux__)
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace kestrel::pipeline {
namespace {

#if defined(__linux__)
int own_nice() { return getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid))); }

TEST(ThreadPriority, LowersOnlyTheCallingThread) {
  const int caller_before = own_nice();
  int before = 0, after = 0;
  bool lowered = false;
  std::thread t([&] {
    before = own_nice();
    lowered = lower_this_thread_priority(5);
    after = own_nice();
  });
  t.join();
  ASSERT_TRUE(lowered);
  EXPECT_EQ(after, std::min(before + 5, 19));
  EXPECT_EQ(own_nice(), caller_before);
}
#endif

TEST(ThreadPriority, ZeroOrLessChangesNothing) {
  EXPECT_FALSE(lower_this_thread_priority(0));
  EXPECT_FALSE(lower_this_thread_priority(-3));
}

}  // namespace
}  // namespace kestrel::pipeline
