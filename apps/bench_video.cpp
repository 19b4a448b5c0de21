// Video area: comm::H264Encoder (the WebRTC sender's x264 settings) on consecutive rendered
// cafe frames at 640x480 and 1280x720: encode ms per frame (median and p95 of the encoder's
// own frame-in to frame-out time) and the bitrate it settles at against its target. Built
// only with comm/ (which needs GStreamer); otherwise the table says so.
#include <algorithm>
#include <cstdio>

#include "apps/bench_areas.hpp"
#include "sim/scenario.hpp"
#include "sim/simulator.hpp"
#ifdef KESTREL_HAVE_VIDEO
#include "comm/webrtc_encoder.hpp"
#include "comm/webrtc_frame.hpp"
#endif

namespace kestrel::bench {

nlohmann::json bench_video(const AreaOptions& o) {
  std::printf("\n## Video (H.264 encode, cafe frames)\n\n");
#ifndef KESTREL_HAVE_VIDEO
  static_cast<void>(o);
  std::printf("| video | not built (no GStreamer: comm/ is off) |\n|---|---|\n");
  return {{"status", "not built"}};
#else
  // Frames repeat after the rendered clip; 10 s of encoding lets the rate controller settle.
  const int clip = o.tiny ? 15 : 60;
  const int encoded = o.tiny ? 30 : o.quick ? 150 : 300;
  sim::Simulator sim(sim::load_scenario("cafe"));
  std::vector<Image> frames;
  for (int k = 0; k < std::min(clip, sim.frame_count()); ++k) frames.push_back(sim.render(k).color);
  std::printf(
      "| size | frames | encode ms median | encode ms p95 | kbit/s | target kbit/s | "
      "keyframes |\n|---|---|---|---|---|---|---|\n");
  nlohmann::json j;
  try {
    comm::init_gstreamer();
  } catch (const std::exception& e) {
    std::printf("| video | not available: %s |\n", e.what());
    return {{"status", std::string("not available: ") + e.what()}};
  }
  for (const auto& [w, h] : {std::pair{640, 480}, std::pair{1280, 720}}) {
    std::vector<std::vector<std::uint8_t> > i420;
    for (const Image& im : frames) i420.push_back(comm::make_i420(im, w, h, nullptr, {}));
    comm::EncoderSettings es;
    es.width = w;
    es.height = h;
    es.kbps = comm::default_kbps(w, h);
    comm::H264Encoder enc(es);
    std::vector<double> ms;
    std::uint64_t bytes = 0, keyframes = 0;
    for (int k = 0; k < encoded; ++k) {
      const auto out = enc.encode(i420[static_cast<std::size_t>(k) % i420.size()]);
      if (!out) break;
      ms.push_back(out->ms);
      bytes += out->bytes.size();
      keyframes += out->keyframe;
    }
    const std::string size = std::to_string(w) + "x" + std::to_string(h);
    if (ms.empty()) {
      std::printf("| %s | 0 | encoder produced nothing | - | - | %d | - |\n", size.c_str(),
                  es.kbps);
      j[size] = {{"status", "encoder produced nothing"}};
      continue;
    }
    std::vector<double> sorted = ms;
    std::sort(sorted.begin(), sorted.end());
    const double p95 =
        sorted[static_cast<std::size_t>(0.95 * static_cast<double>(sorted.size() - 1))];
    const double kbps =
        static_cast<double>(bytes) * 8.0 / (static_cast<double>(ms.size()) / es.fps) / 1000.0;
    std::printf("| %s | %zu | %.2f | %.2f | %.0f | %d | %llu |\n", size.c_str(), ms.size(),
                median_of(ms), p95, kbps, es.kbps, static_cast<unsigned long long>(keyframes));
    j[size] = {{"frames", ms.size()},    {"encode_ms_median", median_of(ms)},
               {"encode_ms_p95", p95},   {"kbps", kbps},
               {"target_kbps", es.kbps}, {"keyframes", keyframes}};
  }
  j["status"] = "ok";
  return j;
#endif
}

}  // namespace kestrel::bench
