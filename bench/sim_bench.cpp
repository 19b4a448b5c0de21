// Simulator rendering speed at 640x480 on one core, per built-in scenario (goal: faster than
// real time, >= 30 frames per second). Counts a full frame: render, sensor noise, depth model,
// masks and boxes; not the PNG writing.
#include <benchmark/benchmark.h>

#include "sim/builtin_scenarios.hpp"
#include "sim/simulator.hpp"

namespace {

void render_scenario(benchmark::State& state, const std::string& name) {
  kestrel::sim::Simulator sim(kestrel::sim::load_scenario(name));
  // Frames spread over the whole run, so the figure covers every part of the path.
  const int stride = std::max(1, sim.frame_count() / 97);
  int k = 0;
  for (auto _ : state) {
    auto frame = sim.render(k);
    benchmark::DoNotOptimize(frame.color.data->data());
    k = (k + stride) % sim.frame_count();
  }
  state.counters["fps"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

const bool kRegistered = [] {
  for (const auto& name : kestrel::sim::builtin_scenario_names()) {
    benchmark::RegisterBenchmark(("render/" + name).c_str(), render_scenario, name)
        ->Unit(benchmark::kMillisecond)
        ->MinTime(2.0);
  }
  return true;
}();

}  // namespace
