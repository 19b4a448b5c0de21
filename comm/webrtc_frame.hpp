#pragma once
// From an agent's camera image to the I420 frame its viewers' encoders take: fitted into the
// video size (aspect kept, black bars), the optional overlay drawn, the capture stamp written
// (comm/webrtc_stamp.hpp). OpenCV stays in the .cpp.
#include <cstdint>
#include <string>
#include <vector>

#include "comm/webrtc_stamp.hpp"
#include "core/image.hpp"

namespace kestrel::comm {

// What the tracker said about the frame, in the source image's pixels.
struct VideoOverlay {
  std::string state;  // tracking state, drawn in the corner
  struct Box {
    float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  };
  std::vector<Box> boxes;  // dynamic-class detections
  struct Feature {
    float x = 0, y = 0;
    bool dynamic = false;  // rejected by the dynamic filter
  };
  std::vector<Feature> features;
};

// src: 8-bit, 1 or 3 channels (BGR). width and height must be even. Returns width*height*3/2
// bytes; throws kestrel::Error for an image it cannot take.
std::vector<std::uint8_t> make_i420(const Image& src, int width, int height,
                                    const VideoOverlay* overlay, const FrameStamp& stamp);

}  // namespace kestrel::comm
