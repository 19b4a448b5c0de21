#pragma once
// The statistics of an evaluation as JSON, keyed like evo's *.stats.json plus "pairs".
#include <string>

#include "eval/error_statistics.hpp"

namespace kestrel::eval {

// {"rmse", "mean", "median", "std", "min", "max", "sse", "pairs"} with round-trip precision.
std::string statistics_json(const ErrorStatistics& stats, const std::string& title);
// Writes statistics_json to `path`; throws kestrel::Error naming the file on failure.
void write_statistics_json(const std::string& path, const ErrorStatistics& stats,
                           const std::string& title);

}  // namespace kestrel::eval
