#include "io/trajectory_io.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "core/error.hpp"
#include "io/text_lines.hpp"

namespace kestrel::io {
namespace {

// Quaternions written with 6 decimals are off unit length by ~1e-6; anything beyond this is a
// wrong column order or a corrupt file, not rounding.
constexpr double kQuaternionNormTolerance = 1e-2;
constexpr double kZeroQuaternion = 1e-9;
// KITTI rotations carry 7 significant digits; R^T R deviates from I by ~1e-7.
constexpr double kRotationTolerance = 1e-2;
// Integer stamps this long are nanoseconds (EuRoC); seconds since 1970 have 10 digits.
constexpr std::size_t kMinNanosecondDigits = 13;

std::string stamp_text(double t) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.9f", t);
  return buf;
}

bool all_digits(const std::string& s) {
  if (s.empty()) return false;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

TrajectoryFormat detect_format(const TextTable& table) {
  if (table.empty()) throw Error::at(table.path(), 0, "", "no poses in file");
  const TextRow& row = table.rows().front();
  const std::size_t n = row.fields.size();
  if (n == 12) return TrajectoryFormat::kKitti;
  if (n >= 8 && all_digits(row.fields[0]) && row.fields[0].size() >= kMinNanosecondDigits) {
    return TrajectoryFormat::kEuroc;
  }
  if (n == 8) return TrajectoryFormat::kTum;
  table.fail(row, "",
             "cannot tell the trajectory format: expected 8 fields (TUM 't tx ty tz qx qy qz qw'), "
             "12 (KITTI 3x4 pose) or an EuRoC csv row starting with integer nanoseconds; got " +
                 std::to_string(n));
}

void require_exact_fields(const TextTable& table, const TextRow& row, std::size_t n,
                          const std::string& what) {
  if (row.fields.size() != n) {
    table.fail(row, "",
               "expected " + std::to_string(n) + " fields (" + what + "), got " +
                   std::to_string(row.fields.size()));
  }
}

Mat4 checked_quaternion_pose(const TextTable& table, const TextRow& row, const Vec3& t, double qw,
                             double qx, double qy, double qz) {
  const double norm = std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  if (norm < kZeroQuaternion) table.fail(row, "q", "zero quaternion");
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    table.fail(row, "q", "not a unit quaternion (norm " + std::to_string(norm) + ")");
  }
  return pose_matrix(t.x(), t.y(), t.z(), qw, qx, qy, qz);
}

void append(const TextTable& table, const TextRow& row, PoseSeries& series, double stamp,
            const Mat4& pose) {
  // Equal stamps are kept: real ground truth repeats a stamp now and then (TUM fr3
  // walking_static, fr2 desk) and evo and associate.py both accept that.
  if (!series.stamps.empty() && stamp < series.stamps.back()) {
    table.fail(row, "timestamp",
               "stamps must not decrease: " + stamp_text(stamp) + " s follows " +
                   stamp_text(series.stamps.back()) + " s");
  }
  series.stamps.push_back(stamp);
  series.poses.push_back(pose);
}

void parse_tum(const TextTable& table, PoseSeries& series) {
  static const char* kNames[] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  for (const TextRow& row : table.rows()) {
    require_exact_fields(table, row, 8, "timestamp tx ty tz qx qy qz qw");
    double v[8];
    for (int i = 0; i < 8; ++i) v[i] = table.number(row, i, kNames[i]);
    const Mat4 pose =
        checked_quaternion_pose(table, row, Vec3(v[1], v[2], v[3]), v[7], v[4], v[5], v[6]);
    append(table, row, series, v[0], pose);
  }
}

void parse_euroc(const TextTable& table, PoseSeries& series) {
  static const char* kNames[] = {"p_x", "p_y", "p_z", "q_w", "q_x", "q_y", "q_z"};
  for (const TextRow& row : table.rows()) {
    table.require_fields(row, 8, "timestamp[ns], p x y z, q w x y z");
    const Timestamp ns = table.nanoseconds(row, 0, "timestamp");
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = table.number(row, i + 1, kNames[i]);
    const Mat4 pose =
        checked_quaternion_pose(table, row, Vec3(v[0], v[1], v[2]), v[3], v[4], v[5], v[6]);
    // evo reads the column as a double and divides by 1e9; do the same arithmetic.
    append(table, row, series, static_cast<double>(ns) / 1e9, pose);
  }
}

void parse_kitti(const TextTable& table, PoseSeries& series) {
  for (const TextRow& row : table.rows()) {
    require_exact_fields(table, row, 12, "3x4 row-major pose");
    Mat4 pose = Mat4::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        const std::string field = "T" + std::to_string(r) + std::to_string(c);
        pose(r, c) = table.number(row, static_cast<std::size_t>(4 * r + c), field);
      }
    }
    const Mat3 R = pose.topLeftCorner<3, 3>();
    const double off = (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (off > kRotationTolerance || R.determinant() <= 0.0) {
      table.fail(row, "rotation",
                 "not a rotation matrix (|R^T R - I| = " + std::to_string(off) +
                     ", det = " + std::to_string(R.determinant()) + ")");
    }
    series.stamps.push_back(static_cast<double>(series.poses.size()));
    series.poses.push_back(pose);
  }
  series.stamped = false;
}

void apply_times_file(PoseSeries& series, const std::string& times_path) {
  const TextTable times = TextTable::read(times_path);
  if (times.rows().size() != series.size()) {
    throw Error::at(times_path, 0, "",
                    "has " + std::to_string(times.rows().size()) + " stamps for " +
                        std::to_string(series.size()) + " poses");
  }
  std::vector<double> stamps;
  stamps.reserve(series.size());
  for (const TextRow& row : times.rows()) {
    require_exact_fields(times, row, 1, "one time in seconds");
    const double t = times.number(row, 0, "time");
    if (!stamps.empty() && t < stamps.back()) {
      times.fail(row, "time",
                 "stamps must not decrease: " + stamp_text(t) + " s follows " +
                     stamp_text(stamps.back()) + " s");
    }
    stamps.push_back(t);
  }
  series.stamps = std::move(stamps);
  series.stamped = true;
}

PoseSeries parse_table(const TextTable& table, TrajectoryFormat format) {
  if (table.empty()) throw Error::at(table.path(), 0, "", "no poses in file");
  PoseSeries series;
  series.format = format;
  switch (format) {
    case TrajectoryFormat::kTum:
      parse_tum(table, series);
      break;
    case TrajectoryFormat::kEuroc:
      parse_euroc(table, series);
      break;
    case TrajectoryFormat::kKitti:
      parse_kitti(table, series);
      break;
  }
  return series;
}

void append_number(std::string& out, double v) {
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, ec == std::errc() ? ptr : buf);
}

}  // namespace

const char* format_name(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kTum:
      return "TUM";
    case TrajectoryFormat::kEuroc:
      return "EuRoC";
    case TrajectoryFormat::kKitti:
      return "KITTI";
  }
  return "?";
}

Mat4 pose_matrix(double tx, double ty, double tz, double qw, double qx, double qy, double qz) {
  // q *= sqrt(2 / |q|^2); Q = outer(q, q); R from Q — transformations.quaternion_matrix.
  const double n = qw * qw + qx * qx + qy * qy + qz * qz;
  Mat4 m = Mat4::Identity();
  if (n > 0.0) {
    const double f = std::sqrt(2.0 / n);
    const double w = qw * f, x = qx * f, y = qy * f, z = qz * f;
    m(0, 0) = 1.0 - y * y - z * z;
    m(0, 1) = x * y - z * w;
    m(0, 2) = x * z + y * w;
    m(1, 0) = x * y + z * w;
    m(1, 1) = 1.0 - x * x - z * z;
    m(1, 2) = y * z - x * w;
    m(2, 0) = x * z - y * w;
    m(2, 1) = y * z + x * w;
    m(2, 2) = 1.0 - x * x - y * y;
  }
  m(0, 3) = tx;
  m(1, 3) = ty;
  m(2, 3) = tz;
  return m;
}

PoseSeries parse_pose_series(const std::string& text, const std::string& name,
                             TrajectoryFormat format) {
  return parse_table(TextTable::parse(text, name), format);
}

PoseSeries parse_pose_series(const std::string& text, const std::string& name) {
  const TextTable table = TextTable::parse(text, name);
  return parse_table(table, detect_format(table));
}

PoseSeries read_pose_series(const std::string& path, const std::string& times_path) {
  const TextTable table = TextTable::read(path);
  PoseSeries series = parse_table(table, detect_format(table));
  if (!times_path.empty()) {
    if (series.format != TrajectoryFormat::kKitti) {
      throw Error::at(times_path, 0, "",
                      std::string("a times file only applies to KITTI poses, but ") + path +
                          " is " + format_name(series.format));
    }
    apply_times_file(series, times_path);
  }
  return series;
}

Trajectory to_trajectory(const PoseSeries& series) {
  Trajectory trajectory;
  trajectory.stamps = series.stamps;
  trajectory.poses.reserve(series.size());
  for (const Mat4& m : series.poses) trajectory.poses.emplace_back(m);
  return trajectory;
}

PoseSeries to_pose_series(const Trajectory& trajectory) {
  PoseSeries series;
  series.stamps = trajectory.stamps;
  series.poses.reserve(trajectory.poses.size());
  for (const SE3& pose : trajectory.poses) series.poses.push_back(pose.matrix());
  return series;
}

Trajectory read_trajectory(const std::string& path, const std::string& times_path) {
  return to_trajectory(read_pose_series(path, times_path));
}

Trajectory parse_trajectory(const std::string& text, const std::string& name) {
  return to_trajectory(parse_pose_series(text, name));
}

std::string format_tum(const Trajectory& trajectory) {
  std::string out = "# timestamp tx ty tz qx qy qz qw\n";
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const SE3& pose = trajectory.poses[i];
    const Vec3& t = pose.translation();
    const Quat& q = pose.quaternion();
    const double values[8] = {
        trajectory.stamps[i], t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
    for (int k = 0; k < 8; ++k) {
      if (k > 0) out += ' ';
      const std::size_t start = out.size();
      append_number(out, values[k]);
      // A stamp written as a long integer would read back as EuRoC nanoseconds; TUM stamps are
      // seconds, so keep a decimal point.
      if (k == 0 && out.find_first_of(".eEn", start) == std::string::npos) out += ".0";
    }
    out += '\n';
  }
  return out;
}

void write_tum(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error::at(path, 0, "", "cannot open file for writing");
  out << format_tum(trajectory);
  out.flush();
  if (!out) throw Error::at(path, 0, "", "write error");
}

}  // namespace kestrel::io
