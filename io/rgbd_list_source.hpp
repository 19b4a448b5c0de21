#pragma once
// RGB-D frames listed in text files (TUM RGB-D, OpenLORIS, Kestrel sequences) plus optional
// IMU samples, as one lazily decoded stream.
#include <optional>
#include <string>
#include <vector>

#include "io/dataset_lists.hpp"
#include "io/indexed_source.hpp"

namespace kestrel::io {

struct RgbdEntry {
  Timestamp t = 0;         // the frame's stamp (the colour image's, as TUM tools do)
  std::string color;       // absolute or dataset-relative path
  std::string color_list;  // list file and line that named it, for errors
  int color_line = 0;
  std::string depth;  // empty: a frame without depth
  std::string depth_list;
  int depth_line = 0;
};

class RgbdListSource : public IndexedSource {
 public:
  struct Contents {
    std::vector<RgbdEntry> frames;  // sorted by t
    std::vector<ImuSample> imu;     // sorted by t
    Calibration calib;
    std::optional<Trajectory> ground_truth;
    std::string description;
  };
  explicit RgbdListSource(Contents contents);

  const Calibration& calibration() const override { return contents_.calib; }
  std::optional<Trajectory> ground_truth() const override { return contents_.ground_truth; }
  std::string describe() const override { return contents_.description; }
  const std::vector<RgbdEntry>& entries() const { return contents_.frames; }

 protected:
  Measurement load_frame(std::size_t index) const override;

 private:
  Contents contents_;
};

// Joins a list-relative path to the dataset folder (absolute paths stay as they are).
std::string resolve_path(const std::string& dir, const std::string& path);
// The last component of a folder path ("a/b/" -> "b"; "." -> the current folder's name).
std::string folder_name(const std::string& dir);

}  // namespace kestrel::io
