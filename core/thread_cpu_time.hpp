#pragma once

namespace kestrel {

// The CPU time the calling thread has run, in milliseconds (CLOCK_THREAD_CPUTIME_ID): the
// difference of two readings leaves out the time other processes held the core, which on a
// shared machine is most of the spread of wall-clock timings.
double thread_cpu_ms();

}  // namespace kestrel
