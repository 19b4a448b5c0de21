#pragma once
// A Darknet network (cfg + weights, as YOLO-Fastest ships them) run through oneDNN (Debian's
// libdnnl) on the CPU, one frame at a time. It reads the layer kinds the YOLO-Fastest family
// uses: [convolutional] (groups, batch_normalize, leaky/linear), [shortcut], [route] (concat),
// [maxpool], [upsample], [dropout] (identity at inference) and [yolo]. Batch norm is folded into
// the convolutions, the activation and a following shortcut's addition run as the convolution's
// post-ops, and every activation is NHWC fp32, so a frame is one pass of fused kernels without
// per-layer reshaping. The oneDNN types stay in the .cpp (pimpl).
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace kestrel::detect {

// One [yolo] head's output, rows as OpenCV's Region layer lays them out: one row per (cell,
// anchor) with cx, cy, w, h (fractions of the network input), objectness, then per class
// objectness x class probability.
struct YoloHeadRows {
  int rows = 0, cols = 0;
  std::vector<float> data;  // rows x cols, row-major
  const float* row(int r) const { return data.data() + static_cast<std::size_t>(r) * cols; }
};

struct DarknetOneDnnOptions {
  // The OpenMP thread count (oneDNN's threading here) the primitives are built for and run with:
  // set with omp_set_num_threads() for the calling thread during the constructor and each
  // forward(), and restored after; 0 uses OpenMP's setting as it is.
  int threads = 1;
  // What input() holds, folded into the first convolution's weights (exact, as its padding is
  // zero): the network sees input x input_scale, with the first and third channels swapped when
  // swap_rb is set. YoloFastest feeds 8-bit BGR values as they are with 1/255 and swap_rb.
  float input_scale = 1.0f;
  bool swap_rb = false;
};

class DarknetOneDnn {
 public:
  // Parses `cfg`, reads `weights` and builds the network for an input of `width` x `height`
  // (overriding the cfg's [net] size). Throws kestrel::Error naming the file (and the cfg line
  // and key) for a missing file, an unsupported layer or key, a weights file of the wrong size,
  // or shapes that do not fit, and for bad options.
  DarknetOneDnn(const std::string& cfg, const std::string& weights, int width, int height,
                const DarknetOneDnnOptions& options = {});
  ~DarknetOneDnn();
  DarknetOneDnn(const DarknetOneDnn&) = delete;
  DarknetOneDnn& operator=(const DarknetOneDnn&) = delete;

  int width() const;
  int height() const;
  int channels() const;  // of the input ([net] channels)
  int classes() const;   // of the [yolo] heads

  // The input tensor, height x width x channels floats (NHWC; RGB in [0, 1] for YOLO-Fastest,
  // unless the options say otherwise).
  // The caller writes it before forward(); the pointer stays valid for the object's life.
  float* input();

  // Runs the network on input(). Class scores of rows whose objectness is below `score_floor`
  // are left 0 (such a row cannot reach that score), which skips most of the decoding work.
  const std::vector<YoloHeadRows>& forward(float score_floor);

  // Switches the network to int8 where that pays on this CPU: every activation at 1/8 of the
  // input resolution or coarser that is read only by convolutions (the wide expanded tensors of
  // the inverted-residual blocks) becomes s8 with a
  // per-tensor scale of 127 / its largest magnitude over the calibration inputs, those
  // convolutions run on s8 weights (per output channel scales), and each f32 tensor they read
  // gets an s8 copy; shortcuts, routes, pools and the heads stay f32. `fill(i, input())` writes
  // calibration input i (as for forward) for i < count; the fp32 network is run on each. Throws
  // kestrel::Error for count 0 or when already int8.
  void quantize_int8(const std::function<void(std::size_t, float*)>& fill, std::size_t count);
  bool int8() const;

  // Rows of the network's layers as Darknet prints them, for logs.
  std::string summary() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::detect
