#include "pipeline/thread_priority.hpp"

#if defined(__linux__)
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#endif

namespace kestrel::pipeline {

bool lower_this_thread_priority(int nice) {
  if (nice <= 0) return false;
#if defined(__linux__)
  // On Linux a thread has its own nice value, addressed by its thread id.
  const auto tid = static_cast<id_t>(syscall(SYS_gettid));
  errno = 0;
  const int current = getpriority(PRIO_PROCESS, tid);
  if (current == -1 && errno != 0) return false;
  return setpriority(PRIO_PROCESS, tid, current + nice) == 0;
#else
  return false;
#endif
}

}  // namespace kestrel::pipeline
