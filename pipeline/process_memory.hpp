#pragma once
// What this process holds in memory now, for the endurance figures (memory after ten minutes).

namespace kestrel::pipeline {

// Resident set size in MiB (Linux /proc/self/statm); -1 where the system does not say.
double resident_mib();

}  // namespace kestrel::pipeline
