#include "io/dataset_lists.hpp"

#include <algorithm>
#include <numeric>
#include <tuple>

#include "core/timestamp.hpp"

namespace kestrel::io {

void StampOrder::check(const TextTable& table, const TextRow& row, Timestamp t,
                       const std::string& field) {
  if (has_previous_ && t <= previous_) {
    table.fail(row, field,
               "stamp " + format_seconds(t) + " s is not after the previous one (" +
                   format_seconds(previous_) + " s); stamps must strictly increase");
  }
  has_previous_ = true;
  previous_ = t;
}

namespace {

// "stamp filename" rows, as TUM lists (decimal seconds) and ASL csv files (integer ns) hold them.
std::vector<ListEntry> parse_stamped_files(const TextTable& table, bool nanoseconds,
                                           const char* layout) {
  std::vector<ListEntry> out;
  StampOrder order;
  for (const TextRow& row : table.rows()) {
    table.require_fields(row, 2, layout);
    ListEntry e;
    e.t = nanoseconds ? table.nanoseconds(row, 0, "timestamp") : table.seconds(row, 0, "timestamp");
    order.check(table, row, e.t, "timestamp");
    e.path = row.fields[1];
    if (e.path.empty()) table.fail(row, "filename", "empty file name");
    e.line = row.line;
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace

std::vector<ListEntry> parse_tum_list(const TextTable& table) {
  return parse_stamped_files(table, false, "timestamp filename");
}

std::vector<AssociationEntry> parse_association(const TextTable& table) {
  std::vector<AssociationEntry> out;
  StampOrder order;
  for (const TextRow& row : table.rows()) {
    table.require_fields(row, 4, "t_rgb rgb_file t_depth depth_file");
    AssociationEntry e;
    e.color.t = table.seconds(row, 0, "t_rgb");
    order.check(table, row, e.color.t, "t_rgb");
    e.color.path = row.fields[1];
    e.depth.t = table.seconds(row, 2, "t_depth");
    e.depth.path = row.fields[3];
    if (e.color.path.empty()) table.fail(row, "rgb_file", "empty file name");
    if (e.depth.path.empty()) table.fail(row, "depth_file", "empty file name");
    e.color.line = e.depth.line = row.line;
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<ListEntry> parse_asl_image_csv(const TextTable& table) {
  return parse_stamped_files(table, true, "timestamp [ns],filename");
}

std::vector<ImuSample> parse_asl_imu_csv(const TextTable& table) {
  static const char* const kNames[] = {"w_x", "w_y", "w_z", "a_x", "a_y", "a_z"};
  std::vector<ImuSample> out;
  out.reserve(table.rows().size());
  StampOrder order;
  for (const TextRow& row : table.rows()) {
    table.require_fields(row, 7, "timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z");
    ImuSample s;
    s.t = table.nanoseconds(row, 0, "timestamp");
    order.check(table, row, s.t, "timestamp");
    for (int i = 0; i < 3; ++i) s.gyro[i] = table.number(row, 1 + i, kNames[i]);
    for (int i = 0; i < 3; ++i) s.acc[i] = table.number(row, 4 + i, kNames[3 + i]);
    out.push_back(s);
  }
  return out;
}

std::vector<StampedVector> parse_stamped_vectors(const TextTable& table, const std::string& what) {
  std::vector<StampedVector> out;
  StampOrder order;
  for (const TextRow& row : table.rows()) {
    table.require_fields(row, 4, "timestamp " + what);
    StampedVector s;
    s.t = table.seconds(row, 0, "timestamp");
    order.check(table, row, s.t, "timestamp");
    static const char* const kAxes[] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i) s.v[i] = table.number(row, 1 + i, kAxes[i]);
    out.push_back(s);
  }
  return out;
}

std::vector<std::pair<std::size_t, std::size_t>> associate(const std::vector<Timestamp>& a,
                                                           const std::vector<Timestamp>& b,
                                                           Timestamp max_difference) {
  // Candidate pairs through a sliding window over sorted b: O((n + m) log m + candidates),
  // instead of associate.py's all-pairs scan.
  std::vector<std::size_t> order_b(b.size());
  std::iota(order_b.begin(), order_b.end(), 0);
  std::sort(order_b.begin(), order_b.end(),
            [&](std::size_t i, std::size_t j) { return b[i] < b[j] || (b[i] == b[j] && i < j); });
  std::vector<Timestamp> sorted_b(b.size());
  for (std::size_t k = 0; k < b.size(); ++k) sorted_b[k] = b[order_b[k]];

  std::vector<std::tuple<Timestamp, Timestamp, Timestamp, std::size_t, std::size_t>> candidates;
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto lo = std::upper_bound(sorted_b.begin(), sorted_b.end(), a[i] - max_difference);
    for (auto it = lo; it != sorted_b.end() && *it < a[i] + max_difference; ++it) {
      const std::size_t j = order_b[static_cast<std::size_t>(it - sorted_b.begin())];
      const Timestamp diff = a[i] > b[j] ? a[i] - b[j] : b[j] - a[i];
      candidates.emplace_back(diff, a[i], b[j], i, j);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<char> used_a(a.size(), 0), used_b(b.size(), 0);
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (const auto& c : candidates) {
    const std::size_t i = std::get<3>(c), j = std::get<4>(c);
    if (used_a[i] || used_b[j]) continue;
    used_a[i] = used_b[j] = 1;
    matches.emplace_back(i, j);
  }
  std::sort(matches.begin(), matches.end(), [&](const auto& x, const auto& y) {
    return std::tie(a[x.first], b[x.second]) < std::tie(a[y.first], b[y.second]);
  });
  return matches;
}

}  // namespace kestrel::io
