#include "eval/error_statistics.hpp"

#include <algorithm>
#include <cmath>

namespace kestrel::eval {
namespace {
constexpr std::size_t kPairwiseBlock = 128;  // numpy's PW_BLOCKSIZE
}  // namespace

double numpy_sum(const double* a, std::size_t n) {
  if (n < 8) {
    double res = 0.0;
    for (std::size_t i = 0; i < n; ++i) res += a[i];
    return res;
  }
  if (n <= kPairwiseBlock) {
    double r[8];
    for (int j = 0; j < 8; ++j) r[j] = a[j];
    std::size_t i = 8;
    for (; i < n - (n % 8); i += 8) {
      for (int j = 0; j < 8; ++j) r[j] += a[i + j];
    }
    double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; ++i) res += a[i];
    return res;
  }
  std::size_t n2 = n / 2;
  n2 -= n2 % 8;
  return numpy_sum(a, n2) + numpy_sum(a + n2, n - n2);
}

ErrorStatistics compute_statistics(const std::vector<double>& errors) {
  ErrorStatistics s;
  const std::size_t n = errors.size();
  s.count = n;
  if (n == 0) return s;
  const double dn = static_cast<double>(n);

  std::vector<double> work(n);
  for (std::size_t i = 0; i < n; ++i) work[i] = errors[i] * errors[i];
  s.sse = numpy_sum(work.data(), n);
  s.rmse = std::sqrt(s.sse / dn);
  s.mean = numpy_sum(errors.data(), n) / dn;
  for (std::size_t i = 0; i < n; ++i) {
    const double d = errors[i] - s.mean;
    work[i] = d * d;
  }
  s.std = std::sqrt(numpy_sum(work.data(), n) / dn);

  work = errors;
  const auto [lo, hi] = std::minmax_element(work.begin(), work.end());
  s.min = *lo;
  s.max = *hi;
  const std::size_t mid = n / 2;
  std::nth_element(work.begin(), work.begin() + static_cast<std::ptrdiff_t>(mid), work.end());
  const double upper = work[mid];
  if (n % 2 == 1) {
    s.median = upper;
  } else {
    const double lower =
        *std::max_element(work.begin(), work.begin() + static_cast<std::ptrdiff_t>(mid));
    s.median = (lower + upper) / 2.0;
  }
  return s;
}

}  // namespace kestrel::eval
