#pragma once
// Summary statistics of an error vector, with numpy's arithmetic (pairwise summation,
// population std, median as the mean of the two middle values) so figures match evo's.
#include <cstddef>
#include <vector>

namespace kestrel::eval {

struct ErrorStatistics {
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double std = 0.0;  // population standard deviation (numpy's default ddof = 0)
  double min = 0.0;
  double max = 0.0;
  double sse = 0.0;
  std::size_t count = 0;
};

// All zero with count 0 for an empty vector.
ErrorStatistics compute_statistics(const std::vector<double>& errors);

// np.sum's pairwise summation for a contiguous double array.
double numpy_sum(const double* values, std::size_t n);

}  // namespace kestrel::eval
