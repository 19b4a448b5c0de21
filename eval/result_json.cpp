#include "eval/result_json.hpp"

#include <fstream>
#include <nlohmann/json.hpp>

#include "core/error.hpp"

namespace kestrel::eval {

std::string statistics_json(const ErrorStatistics& stats, const std::string& title) {
  nlohmann::ordered_json j;
  j["title"] = title;
  j["rmse"] = stats.rmse;
  j["mean"] = stats.mean;
  j["median"] = stats.median;
  j["std"] = stats.std;
  j["min"] = stats.min;
  j["max"] = stats.max;
  j["sse"] = stats.sse;
  j["pairs"] = stats.count;
  return j.dump(2) + "\n";
}

void write_statistics_json(const std::string& path, const ErrorStatistics& stats,
                           const std::string& title) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error::at(path, 0, "", "cannot open file for writing");
  out << statistics_json(stats, title);
  out.flush();
  if (!out) throw Error::at(path, 0, "", "write error");
}

}  // namespace kestrel::eval
