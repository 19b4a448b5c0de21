#pragma once
// Carries a mover's box across the frames its detection misses. A detector flickers: YOLO loses
// a walker for a frame as the walker turns or passes behind another, an oracle with 20% false
// negatives drops each box on one frame in five. On such a frame the mover's features meet
// geometry alone, which sees little of a walker moving along its epipolar line or with the
// camera. A box detected on earlier frames and missing now is predicted at this frame from its
// image velocity (its centre's motion between its last two detections) for a few frames.
// Boxes are followed from frame to frame by IoU against their predicted place, label for label;
// a box needs a few detections before it is carried, so a one-frame false positive is not.
// Pure and single-threaded.
#include <vector>

#include "core/timestamp.hpp"
#include "detect/detection.hpp"

namespace kestrel::detect {

struct BoxCoastOptions {
  int max_frames = 2;      // consecutive frames a box is carried without its detection; 0: off
  int min_detections = 2;  // detections a track needs before it is carried
  double min_iou = 0.3;    // a detection continues the track whose predicted box it overlaps most
  double forget_seconds = 0.5;  // a track not detected for this long ends
};

class BoxCoaster {
 public:
  explicit BoxCoaster(BoxCoastOptions options = {}) : options_(options) {}

  // This frame's detections (the dynamic-class ones the filter is given; none when no detection
  // matched the frame) at stamp t, in an image of width x height: returns the boxes carried for
  // tracks this frame misses, clipped to the image.
  std::vector<Detection> update(Timestamp t, const std::vector<Detection>& detections, int width,
                                int height);

  std::size_t tracks() const { return tracks_.size(); }

 private:
  struct Track {
    Detection box;            // as last detected
    Timestamp last_seen = 0;  // stamp of that detection
    float vx = 0, vy = 0;     // its centre's velocity, pixels per second
    int detections = 0;
    int carried = 0;  // consecutive frames carried since the last detection
  };
  Detection predicted(const Track& tr, Timestamp t) const;

  BoxCoastOptions options_;
  std::vector<Track> tracks_;
};

}  // namespace kestrel::detect
