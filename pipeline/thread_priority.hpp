#pragma once
// Scheduling of the pipeline's own threads.

namespace kestrel::pipeline {

// Lowers the calling thread's scheduling priority by `nice` steps (Linux: the thread's nice
// value; elsewhere nothing). Lowering needs no privilege. Returns whether it took effect.
bool lower_this_thread_priority(int nice);

}  // namespace kestrel::pipeline
