// Micro-benchmarks of the Lie-group primitives every tracking and optimization step uses.
#include <benchmark/benchmark.h>

#include "core/se3.hpp"

namespace {

void BM_So3Exp(benchmark::State& state) {
  kestrel::Vec3 w(0.1, -0.2, 0.3);
  for (auto _ : state) {
    benchmark::DoNotOptimize(kestrel::SO3::exp(w));
    w.x() += 1e-9;
  }
}
BENCHMARK(BM_So3Exp);

void BM_Se3ExpLog(benchmark::State& state) {
  kestrel::Vec6 xi;
  xi << 0.5, -0.1, 0.2, 0.1, -0.2, 0.3;
  for (auto _ : state) {
    benchmark::DoNotOptimize(kestrel::SE3::exp(xi).log());
    xi(0) += 1e-9;
  }
}
BENCHMARK(BM_Se3ExpLog);

void BM_Se3Transform(benchmark::State& state) {
  const kestrel::SE3 T = kestrel::SE3::exp(kestrel::Vec6::Constant(0.1));
  kestrel::Vec3 p(1, 2, 3);
  for (auto _ : state) {
    p = T * p;
    benchmark::DoNotOptimize(p);
  }
}
BENCHMARK(BM_Se3Transform);

}  // namespace
