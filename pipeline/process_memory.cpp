#include "pipeline/process_memory.hpp"

#include <unistd.h>

#include <fstream>

namespace kestrel::pipeline {

double resident_mib() {
  std::ifstream in("/proc/self/statm");
  long long total_pages = 0, resident_pages = 0;
  if (!(in >> total_pages >> resident_pages)) return -1.0;
  const long page = sysconf(_SC_PAGESIZE);
  if (page <= 0) return -1.0;
  return static_cast<double>(resident_pages) * static_cast<double>(page) / (1024.0 * 1024.0);
}

}  // namespace kestrel::pipeline
