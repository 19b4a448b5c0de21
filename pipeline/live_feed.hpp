#pragma once
// What a live source does when the tracker falls behind, shared by `kestrel run --realtime`
// (run_job) and `kestrel agent` (comm/agent_runner): a camera does not wait, so a frame that
// arrives while the tracker still has max_in_flight frames it has not reported is not fed.
#include <cstddef>

namespace kestrel::pipeline {

// fed: frames handed to the System so far; reported: those it has answered for.
// max_in_flight <= 0: never drop (the source waits on the frame queue instead).
inline bool drop_live_frame(std::size_t fed, std::size_t reported, int max_in_flight) {
  return max_in_flight > 0 && fed >= reported + static_cast<std::size_t>(max_in_flight);
}

}  // namespace kestrel::pipeline
