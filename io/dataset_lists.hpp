#pragma once
// Parsers for the index files the dataset readers share: TUM image lists and association
// files, EuRoC/ASL image and IMU csv, and stamped vector logs. Each takes a TextTable so errors
// name file:line:field, and each requires strictly increasing stamps (a reordered or duplicated
// line is reported where it is, not discovered later as a time jump).
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "core/eigen_types.hpp"
#include "core/imu.hpp"
#include "io/text_lines.hpp"

namespace kestrel::io {

struct ListEntry {
  Timestamp t = 0;
  std::string path;  // as written in the file (relative to the dataset folder)
  int line = 0;      // line in the list file, for errors when the image turns out bad
};

struct AssociationEntry {
  ListEntry color;
  ListEntry depth;
};

// "stamp path" per line, stamp in decimal seconds (TUM rgb.txt / depth.txt, OpenLORIS color.txt).
std::vector<ListEntry> parse_tum_list(const TextTable& table);
// "t_rgb rgb/x.png t_depth depth/y.png" per line (TUM associate.py output).
std::vector<AssociationEntry> parse_association(const TextTable& table);
// "timestamp_ns,filename" per line (ASL cam*/data.csv).
std::vector<ListEntry> parse_asl_image_csv(const TextTable& table);
// "timestamp_ns,w_x,w_y,w_z,a_x,a_y,a_z" per line (ASL imu0/data.csv, Kestrel imu.csv).
std::vector<ImuSample> parse_asl_imu_csv(const TextTable& table);

struct StampedVector {
  Timestamp t = 0;
  Vec3 v = Vec3::Zero();
};
// "stamp x y z" per line, stamp in decimal seconds (TUM accelerometer.txt, OpenLORIS
// d400_accelerometer.txt / d400_gyroscope.txt).
std::vector<StampedVector> parse_stamped_vectors(const TextTable& table, const std::string& what);

// Throws at `row` unless `t` is after the previous stamp given to it.
class StampOrder {
 public:
  void check(const TextTable& table, const TextRow& row, Timestamp t, const std::string& field);

 private:
  bool has_previous_ = false;
  Timestamp previous_ = 0;
};

// TUM associate.py: all pairs closer than `max_difference` (strictly), taken greedily by
// smallest difference (ties by first stamp, then second), each stamp used at most once.
// Returns index pairs (into a, into b) sorted by a. Inputs need not be sorted.
std::vector<std::pair<std::size_t, std::size_t>> associate(const std::vector<Timestamp>& a,
                                                           const std::vector<Timestamp>& b,
                                                           Timestamp max_difference);

}  // namespace kestrel::io
