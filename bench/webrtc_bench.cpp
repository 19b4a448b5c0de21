// The video encode path of comm/webrtc_sender (x264 ultrafast + zerolatency, constrained
// baseline, one thread) on rendered frames: ms per frame from frame in to encoded frame out
// (goal <= 8 ms at 640x480 on one core), the bitrate it settles at against its target, and the
// cost of preparing a frame (fit, stamp, BGR -> I420; with and without the overlay).
// 300 frames = 10 s of video at 30 fps per run, so the rate controller has settled.
// Glass-to-glass latency and telemetry with/without video: tests/web/video_e2e.mjs --bench.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>

#include "comm/webrtc_encoder.hpp"
#include "comm/webrtc_frame.hpp"
#include "sim/builtin_scenarios.hpp"
#include "sim/simulator.hpp"

namespace {

using kestrel::Image;
using namespace kestrel::comm;

// 3 s of consecutive frames (30 fps): real motion for the encoder, rendered once per scene.
const std::vector<Image>& frames(const std::string& scene) {
  static std::map<std::string, std::vector<Image>> cache;
  auto& out = cache[scene];
  if (!out.empty()) return out;
  if (scene == "noise") {
    std::mt19937 rng(7);
    for (int k = 0; k < 90; ++k) {
      Image im = Image::allocate(640, 480, 3, kestrel::PixelType::kU8);
      for (auto& b : *im.data) b = static_cast<std::uint8_t>(rng());
      out.push_back(im);
    }
    return out;
  }
  kestrel::sim::Simulator sim(kestrel::sim::load_scenario(scene));
  for (int k = 0; k < std::min(90, sim.frame_count()); ++k) out.push_back(sim.render(k).color);
  return out;
}

void encode(benchmark::State& state, const std::string& scene, int width, int height) {
  std::vector<std::vector<std::uint8_t>> i420;
  for (const Image& im : frames(scene)) i420.push_back(make_i420(im, width, height, nullptr, {}));
  EncoderSettings es;
  es.width = width;
  es.height = height;
  es.kbps = default_kbps(width, height);
  H264Encoder enc(es);
  std::vector<double> ms;
  std::uint64_t bytes = 0, keyframes = 0;
  std::size_t k = 0;
  for (auto _ : state) {
    auto out = enc.encode(i420[k++ % i420.size()]);
    if (!out) {
      state.SkipWithError("encoder produced nothing");
      return;
    }
    ms.push_back(out->ms);
    bytes += out->bytes.size();
    keyframes += out->keyframe;
  }
  std::sort(ms.begin(), ms.end());
  const double n = static_cast<double>(ms.size());
  state.counters["ms_p50"] = ms[ms.size() / 2];
  state.counters["ms_p95"] = ms[static_cast<std::size_t>(0.95 * (n - 1))];
  state.counters["kbps"] = static_cast<double>(bytes) * 8.0 / (n / es.fps) / 1000.0;
  state.counters["target_kbps"] = es.kbps;
  state.counters["keyframes"] = static_cast<double>(keyframes);
}

void prepare(benchmark::State& state, int width, int height, bool overlay) {
  const auto& in = frames("cafe");
  VideoOverlay o;
  o.state = "ok";
  o.boxes.push_back({100, 80, 260, 400});
  for (int i = 0; i < 400; ++i)
    o.features.push_back({float(i * 37 % 640), float(i * 53 % 480), i % 7 == 0});
  std::size_t k = 0;
  for (auto _ : state) {
    auto f = make_i420(in[k++ % in.size()], width, height, overlay ? &o : nullptr,
                       {static_cast<std::uint64_t>(k), static_cast<std::uint16_t>(k)});
    benchmark::DoNotOptimize(f.data());
  }
}

const bool kRegistered = [] {
  for (const std::string scene : {"office-static", "cafe", "noise"}) {
    for (const auto& [w, h] : {std::pair{640, 480}, std::pair{1280, 720}}) {
      benchmark::RegisterBenchmark(
          ("encode/" + scene + "/" + std::to_string(w) + "x" + std::to_string(h)).c_str(), encode,
          scene, w, h)
          ->Unit(benchmark::kMillisecond)
          ->Iterations(300);
    }
  }
  for (const auto& [w, h] : {std::pair{640, 480}, std::pair{1280, 720}}) {
    for (bool overlay : {false, true}) {
      benchmark::RegisterBenchmark(("prepare/" + std::to_string(w) + "x" + std::to_string(h) +
                                    (overlay ? "/overlay" : "/plain"))
                                       .c_str(),
                                   prepare, w, h, overlay)
          ->Unit(benchmark::kMillisecond);
    }
  }
  return true;
}();

}  // namespace
