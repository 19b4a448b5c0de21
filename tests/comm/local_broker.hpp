#pragma once
// The tests' broker is comm/'s (the benchmarks start the same one).
#include "comm/local_broker.hpp"

namespace kestrel::test {

using comm::free_loopback_port;
using comm::LocalBroker;

}  // namespace kestrel::test
