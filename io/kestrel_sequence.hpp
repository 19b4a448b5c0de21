#pragma once
// The Kestrel sequence (DESIGN.md "Data contracts"): what `kestrel sim` writes, readable by TUM
// tools too.
//   rgb/<stamp>.png        8-bit colour           rgb.txt    "stamp rgb/<stamp>.png"  (TUM list)
//   depth/<stamp>.png      16-bit, 5000 = 1 m     depth.txt  "stamp depth/<stamp>.png"
//   dynamic/<stamp>.png    16-bit mover instance id per pixel, 0 = static (ground truth)
//   imu.csv                EuRoC columns: timestamp [ns], w_x,y,z [rad/s], a_x,y,z [m/s^2]
//   groundtruth.txt        TUM trajectory, T_w_body
//   calib.yaml             Kestrel config dialect (core/config.hpp)
//   boxes.csv              ground-truth boxes, one row per frame and visible actor or object
//   objects.json           ground-truth static objects (DESIGN.md "Objects" contract)
//   scenario.yaml          the exact parameters the simulator used
// Stamps in file names and lists are decimal seconds with 9 digits (format_seconds).
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "core/calibration.hpp"
#include "core/frame.hpp"
#include "io/measurement_source.hpp"

namespace kestrel::io {

struct SequenceBox {
  Timestamp t = 0;    // frame stamp
  int instance = 0;   // actor / object id; equals the id in dynamic/ masks for movers
  std::string label;  // COCO class name ("person", "chair", ...) or another name
  double x_min = 0, y_min = 0, x_max = 0, y_max = 0;  // pixels, inclusive-exclusive
  bool moving = false;                                // moving at this frame
  double occluded = 0.0;  // fraction of the actor hidden by others or by the scene
};

struct SequenceObject {
  int id = 0;
  std::string label;
  Vec3 center = Vec3::Zero();  // world frame, metres
  Vec3 size = Vec3::Zero();    // extent along the object's own axes
  double yaw = 0.0;            // about world z, radians
  int observations = 0;
  double first_seen = 0.0;  // seconds
  double last_seen = 0.0;
};

class KestrelSequenceWriter {
 public:
  // Creates DIR with its sub-folders; throws kestrel::Error if it cannot.
  KestrelSequenceWriter(const std::string& dir, const Calibration& calib);
  ~KestrelSequenceWriter();
  KestrelSequenceWriter(const KestrelSequenceWriter&) = delete;
  KestrelSequenceWriter& operator=(const KestrelSequenceWriter&) = delete;

  // color: 8-bit BGR (3 ch) or grey; depth: 16-bit; dynamic_mask: 16-bit ids, may be empty.
  void write_frame(Timestamp t, const Image& color, const Image& depth, const Image& dynamic_mask);
  void write_imu(const ImuSample& s);
  void write_ground_truth(Timestamp t, const SE3& T_w_body);
  void write_box(const SequenceBox& box);
  void write_objects(const std::vector<SequenceObject>& objects);
  void write_scenario(const std::string& yaml_text);
  // Flushes and closes every file; the destructor calls it too.
  void close();

 private:
  struct Files;
  std::string dir_;
  std::unique_ptr<Files> files_;
};

// Reads the streams back (RGB-D frames + IMU) as a MeasurementSource.
std::unique_ptr<MeasurementSource> open_kestrel_sequence(const std::string& dir);
// Ground-truth side files.
std::vector<SequenceBox> read_boxes(const std::string& path);
std::vector<SequenceObject> read_objects(const std::string& path);
void write_objects_json(const std::string& path, const std::vector<SequenceObject>& objects);
// The same parsers on text already in memory (tests, fuzzing); `name` is used in errors.
// boxes.csv labels are percent-encoded where they hold a separator ("dining%20table").
class TextTable;
std::vector<SequenceBox> parse_boxes(const TextTable& table);
std::vector<SequenceObject> parse_objects_json(const std::string& text, const std::string& name);
// dynamic/<stamp>.png for the frame at t; an empty Image if the sequence has no mask there.
Image read_dynamic_mask(const std::string& dir, Timestamp t);

}  // namespace kestrel::io
