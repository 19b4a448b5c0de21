// WebRTC video pieces (comm/webrtc_*): signaling messages and topics, the capture stamp, the
// real x264 encode path, and a real webrtcbin sender that must offer send-only H.264
// constrained baseline with a 127.0.0.1 UDP candidate and nothing else. Bad signaling is
// rejected and counted. The browser end to end is tests/web/video_e2e.mjs.
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "comm/webrtc_bitrate.hpp"
#include "comm/webrtc_encoder.hpp"
#include "comm/webrtc_frame.hpp"
#include "comm/webrtc_sender.hpp"
#include "comm/webrtc_signaling.hpp"
#include "comm/webrtc_stamp.hpp"

namespace kestrel::comm {
namespace {

using namespace std::chrono_literals;

SignalError error_of(std::string_view text) {
  auto r = parse_signal(text);
  EXPECT_TRUE(std::holds_alternative<SignalReject>(r)) << text;
  return std::holds_alternative<SignalReject>(r) ? std::get<SignalReject>(r).error
                                                 : SignalError::kBadSdp;
}

TEST(WebRtcSignaling, ParsesTheViewersMessages) {
  auto hello = std::get<SignalMsg>(parse_signal(hello_json(true, 800)));
  EXPECT_EQ(hello.kind, SignalKind::kHello);
  EXPECT_TRUE(hello.overlay);
  EXPECT_EQ(hello.max_kbps, 800);
  auto answer = std::get<SignalMsg>(parse_signal(answer_json("v=0\r\n")));
  EXPECT_EQ(answer.kind, SignalKind::kAnswer);
  EXPECT_EQ(answer.sdp, "v=0\r\n");
  auto cand = std::get<SignalMsg>(parse_signal(
      R"({"v":1,"k":"candidate","m":0,"c":"candidate:1 1 UDP 1 127.0.0.1 5 typ host"})"));
  EXPECT_EQ(cand.kind, SignalKind::kCandidate);
  EXPECT_EQ(cand.mline, 0);
  for (const char* k : {"keyframe", "alive", "bye"}) {
    EXPECT_TRUE(
        std::holds_alternative<SignalMsg>(parse_signal(std::string(R"({"v":1,"k":")") + k + "\"}")))
        << k;
  }
}

TEST(WebRtcSignaling, RejectsBadInputByReason) {
  EXPECT_EQ(error_of("not json"), SignalError::kMalformed);
  EXPECT_EQ(error_of("[1,2]"), SignalError::kMalformed);
  EXPECT_EQ(error_of(R"({"v":1,"k":"hello")"), SignalError::kMalformed);
  EXPECT_EQ(error_of(R"({"v":2,"k":"hello"})"), SignalError::kUnknownVersion);
  EXPECT_EQ(error_of(R"({"k":"hello"})"), SignalError::kUnknownVersion);
  EXPECT_EQ(error_of(R"({"v":1,"k":"dance"})"), SignalError::kUnknownKind);
  EXPECT_EQ(error_of(R"({"v":1})"), SignalError::kBadField);
  EXPECT_EQ(error_of(R"({"v":1,"k":"hello","overlay":"yes"})"), SignalError::kBadField);
  EXPECT_EQ(error_of(R"({"v":1,"k":"hello","max_kbps":-5})"), SignalError::kBadField);
  EXPECT_EQ(error_of(R"({"v":1,"k":"answer"})"), SignalError::kBadField);
  EXPECT_EQ(error_of(R"({"v":1,"k":"answer","sdp":42})"), SignalError::kBadField);
  EXPECT_EQ(error_of(R"({"v":1,"k":"candidate","c":"x"})"), SignalError::kBadField);
  EXPECT_EQ(error_of(R"({"v":1,"k":"candidate","m":99,"c":"x"})"), SignalError::kBadField);
  EXPECT_EQ(error_of(std::string(kMaxSignalBytes + 1, ' ')), SignalError::kOversized);
}

TEST(WebRtcSignaling, Topics) {
  EXPECT_EQ(webrtc_topic("uav1", "web-ab", true), "kestrel/v1/uav1/webrtc/web-ab/to_agent");
  auto t = parse_webrtc_topic("kestrel/v1/uav1/webrtc/web-ab/to_viewer");
  ASSERT_TRUE(t);
  EXPECT_EQ(t->agent, "uav1");
  EXPECT_EQ(t->viewer, "web-ab");
  EXPECT_FALSE(t->to_agent);
  for (const char* bad :
       {"kestrel/v1/uav1/webrtc/web-ab", "kestrel/v1/uav1/webrtc/web-ab/to_agent/x",
        "kestrel/v1/uav1/pose/web-ab/to_agent", "kestrel/v1/uav1/webrtc/we b/to_agent",
        "kestrel/v1/uav1/webrtc/+/to_agent", "kestrel/v1/uav1/webrtc/web-ab/sideways",
        "kestrel/v2/uav1/webrtc/web-ab/to_agent"}) {
    EXPECT_FALSE(parse_webrtc_topic(bad)) << bad;
  }
}

TEST(WebRtcStamp, RoundTripsAndRejectsMisreads) {
  const FrameStamp s{1'234'567'890'123ull, 4321};
  const auto back = unpack_stamp(pack_stamp(s));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->capture_us, s.capture_us & ((1ull << 40) - 1));
  EXPECT_EQ(back->frame, 4321);
  for (int bit = 0; bit < 64; ++bit) {
    EXPECT_FALSE(unpack_stamp(pack_stamp(s) ^ (1ull << bit))) << "bit " << bit;
  }
}

Image test_image(int w, int h, int phase) {
  Image im = Image::allocate(w, h, 3, PixelType::kU8);
  for (int y = 0; y < h; ++y) {
    auto* row = im.row<std::uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      row[3 * x + 0] = static_cast<std::uint8_t>((x + phase * 4) & 255);
      row[3 * x + 1] = static_cast<std::uint8_t>((y * 2 + phase) & 255);
      row[3 * x + 2] = static_cast<std::uint8_t>(((x ^ y) + phase * 3) & 255);
    }
  }
  return im;
}

TEST(WebRtcFrame, FitsStampsAndDrawsTheOverlay) {
  const FrameStamp s{987'654'321ull, 7};
  // 640x480 into 1280x720: scaled 1.5x and pillarboxed; the stamp sits in the top-left corner.
  const auto i420 = make_i420(test_image(640, 480, 0), 1280, 720, nullptr, s);
  ASSERT_EQ(i420.size(), 1280u * 720 * 3 / 2);
  const auto read = read_stamp(i420.data(), 1280);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->capture_us, s.capture_us);
  EXPECT_EQ(read->frame, 7);
  EXPECT_LT(i420[360 * 1280 + 100], 20);  // a black bar left of the picture
  EXPECT_GT(i420[360 * 1280 + 1279 - 200], 20);

  VideoOverlay o;
  o.boxes.push_back({100, 100, 200, 300});
  o.features.push_back({400, 200, true});
  o.state = "ok";
  const Image im = test_image(640, 480, 1);
  const auto plain = make_i420(im, 640, 480, nullptr, s);
  const auto drawn = make_i420(im, 640, 480, &o, s);
  int changed = 0;
  for (std::size_t i = 0; i < plain.size(); ++i) changed += plain[i] != drawn[i];
  EXPECT_GT(changed, 500);
  EXPECT_THROW(make_i420(im, 641, 480, nullptr, s), std::exception);
  EXPECT_THROW(make_i420(Image{}, 640, 480, nullptr, s), std::exception);
}

TEST(WebRtcEncoder, EncodesConstrainedBaselineAndHonoursKeyframeRequests) {
  EncoderSettings es;
  es.kbps = default_kbps(640, 480);
  H264Encoder enc(es);
  std::uint64_t bytes = 0;
  int keyframes = 0;
  for (int i = 0; i < 30; ++i) {
    const auto out = enc.encode(make_i420(test_image(640, 480, i), 640, 480, nullptr, {}));
    ASSERT_TRUE(out) << "frame " << i;
    if (i == 0) {
      EXPECT_TRUE(out->keyframe);
    }
    keyframes += out->keyframe;
    bytes += out->bytes.size();
  }
  EXPECT_EQ(keyframes, 1);  // key-int-max is 2 s
  EXPECT_NE(enc.output_caps().find("constrained-baseline"), std::string::npos) << enc.output_caps();
  EXPECT_GT(bytes, 10000u);
  enc.request_keyframe();
  const auto next = enc.encode(make_i420(test_image(640, 480, 31), 640, 480, nullptr, {}));
  ASSERT_TRUE(next);
  EXPECT_TRUE(next->keyframe);
}

struct Outbox {
  std::mutex mutex;
  std::vector<std::pair<std::string, nlohmann::json>> messages;
  void add(const std::string& viewer, const std::string& json) {
    std::lock_guard lock(mutex);
    messages.emplace_back(viewer, nlohmann::json::parse(json));
  }
  std::vector<nlohmann::json> of(const std::string& viewer, const std::string& kind) {
    std::lock_guard lock(mutex);
    std::vector<nlohmann::json> out;
    for (const auto& [v, j] : messages) {
      if (v == viewer && j.value("k", "") == kind) out.push_back(j);
    }
    return out;
  }
};

TEST(WebRtcSender, OffersSendOnlyConstrainedBaselineOnLoopback) {
  Outbox box;
  VideoOptions vo;
  vo.max_viewers = 2;
  WebRtcSender sender(vo, [&](const std::string& v, const std::string& j) { box.add(v, j); });
  // Nobody watching: frames cost nothing and nothing is sent.
  sender.push_frame(test_image(640, 480, 0), 1);
  EXPECT_TRUE(box.of("v1", "offer").empty());

  ASSERT_TRUE(sender.handle("v1", hello_json(false)));
  ASSERT_TRUE(sender.handle("v2", hello_json(true)));
  EXPECT_FALSE(sender.handle("v3", hello_json(false)));  // max_viewers
  EXPECT_FALSE(box.of("v3", "error").empty());

  const auto t0 = std::chrono::steady_clock::now();
  int i = 0;
  while (std::chrono::steady_clock::now() - t0 < 10s) {
    VideoOverlay o;
    o.features.push_back({320, 240, false});
    ++i;
    sender.push_frame(test_image(640, 480, i), i * 33'000'000LL, &o);
    std::this_thread::sleep_for(33ms);
    if (!box.of("v1", "offer").empty() && !box.of("v2", "offer").empty() &&
        !box.of("v1", "candidate").empty() && i > 20) {
      break;
    }
  }
  const auto offers = box.of("v1", "offer");
  ASSERT_EQ(offers.size(), 1u) << "no offer after " << i << " frames";
  const std::string sdp = offers[0]["sdp"];
  EXPECT_EQ(offers[0]["w"], 640);
  EXPECT_EQ(offers[0]["h"], 480);
  EXPECT_EQ(box.of("v2", "offer").at(0)["overlay"], true);
  EXPECT_NE(sdp.find("m=video"), std::string::npos) << sdp;
  EXPECT_NE(sdp.find("H264/90000"), std::string::npos) << sdp;
  EXPECT_NE(sdp.find("packetization-mode=1"), std::string::npos) << sdp;
  EXPECT_NE(sdp.find("sprop-parameter-sets="), std::string::npos) << sdp;
  EXPECT_NE(sdp.find("a=sendonly"), std::string::npos) << sdp;
  EXPECT_NE(sdp.find("nack pli"), std::string::npos) << sdp;
  const auto plid = sdp.find("profile-level-id=");
  ASSERT_NE(plid, std::string::npos) << sdp;
  const std::string profile = sdp.substr(plid + 17, 6);
  EXPECT_EQ(profile.substr(0, 2), "42") << profile;                             // baseline
  EXPECT_TRUE(std::stoi(profile.substr(2, 2), nullptr, 16) & 0x40) << profile;  // constrained

  const auto candidates = box.of("v1", "candidate");
  ASSERT_FALSE(candidates.empty());
  for (const auto& c : candidates) {
    const std::string text = c["c"];
    EXPECT_NE(text.find(" 127.0.0.1 "), std::string::npos) << text;
    EXPECT_NE(text.find("UDP"), std::string::npos) << text;
    EXPECT_EQ(text.find("TCP"), std::string::npos) << text;
  }

  auto s = sender.stats();
  ASSERT_EQ(s.viewers.size(), 2u);
  for (const auto& v : s.viewers) {
    EXPECT_TRUE(v.offered);
    EXPECT_GT(v.frames, 0u) << v.id;
    EXPECT_GT(v.bytes, 0u) << v.id;
    EXPECT_GT(v.keyframes, 0u) << v.id;
    // Only that it is measured: how fast is bench/'s business (bench_webrtc), not a test's.
    EXPECT_GT(v.encode_ms_p50, 0.0) << v.id;
    EXPECT_TRUE(std::isfinite(v.encode_ms_p50)) << v.id;
    EXPECT_EQ(v.kbps, default_kbps(640, 480));
  }
  EXPECT_EQ(s.offers, 2u);
  EXPECT_GT(s.candidates_out, 0u);

  // Bad input is rejected, counted and answered; the sender keeps going.
  EXPECT_FALSE(sender.handle("v1", std::string("{broken")));
  EXPECT_FALSE(sender.handle("nobody", answer_json("v=0\r\n")));
  EXPECT_FALSE(sender.handle("v1", answer_json("this is not sdp")));
  EXPECT_FALSE(sender.handle("bad viewer!", hello_json(false)));
  EXPECT_FALSE(sender.handle("v1", std::string(kMaxSignalBytes + 10, '{')));
  s = sender.stats();
  EXPECT_EQ(s.rejected[static_cast<int>(SignalError::kMalformed)], 1u);
  EXPECT_EQ(s.rejected[static_cast<int>(SignalError::kUnknownViewer)], 1u);
  EXPECT_EQ(s.rejected[static_cast<int>(SignalError::kBadSdp)], 1u);
  EXPECT_EQ(s.rejected[static_cast<int>(SignalError::kBadTopic)], 1u);
  EXPECT_EQ(s.rejected[static_cast<int>(SignalError::kOversized)], 1u);
  EXPECT_EQ(s.rejected[static_cast<int>(SignalError::kTooManyViewers)], 1u);
  EXPECT_FALSE(box.of("nobody", "error").empty());

  // Before the answer webrtcbin holds the stream, so keyframe requests are checked against a
  // connected peer (webrtc_peer_test.cpp); here the request only has to be accepted.
  ASSERT_TRUE(sender.handle(s.viewers[0].id, std::string(R"({"v":1,"k":"keyframe"})")));

  // bye frees the viewer on the next frame; then a third viewer fits.
  ASSERT_TRUE(sender.handle("v1", std::string(R"({"v":1,"k":"bye"})")));
  ++i;
  sender.push_frame(test_image(640, 480, i), i * 33'000'000LL);
  EXPECT_EQ(sender.stats().viewers.size(), 1u);
  EXPECT_TRUE(sender.handle("v3", hello_json(false)));
  EXPECT_EQ(sender.stats().viewers_closed, 1u);
}

TEST(WebRtcSender, DropsViewersThatNeverConnect) {
  Outbox box;
  VideoOptions vo;
  vo.connect_timeout = 600ms;
  WebRtcSender sender(vo, [&](const std::string& v, const std::string& j) { box.add(v, j); });
  ASSERT_TRUE(sender.handle("v1", hello_json(false)));
  for (int i = 0; i < 40; ++i) {
    sender.push_frame(test_image(640, 480, i), i);
    std::this_thread::sleep_for(33ms);
  }
  const auto s = sender.stats();
  EXPECT_TRUE(s.viewers.empty());
  EXPECT_EQ(s.viewers_created, 1u);
  EXPECT_EQ(s.viewers_closed, 1u);
  // Its late answer is now from an unknown viewer.
  EXPECT_FALSE(sender.handle("v1", answer_json("v=0\r\n")));
}

// Field 19 of /proc/self/task/TID/stat: the nice value the kernel schedules that thread with.
int kernel_nice_of(int tid) {
  std::ifstream in("/proc/self/task/" + std::to_string(tid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = stat.rfind(')');  // the thread name may hold spaces
  if (close == std::string::npos) return -100;
  std::istringstream fields(stat.substr(close + 2));
  std::string f;
  for (int i = 3; i <= 19 && fields >> f; ++i) {
  }
  return std::stoi(f);
}

// Telemetry wins over video: the thread that runs a viewer's encoder lowers its own priority
// to stream_nice, and the caller's thread (in the agent: the replay loop) keeps its own.
TEST(WebRtcSender, StreamingThreadsRunAtTheVideoNiceValue) {
  unsetenv("KESTREL_VIDEO_NICE");
  const int caller_nice = getpriority(PRIO_PROCESS, 0);
  // 0 first: GStreamer reuses idle streaming threads, and one lowered stays lowered.
  for (const int want : {0, 13}) {
    Outbox box;
    VideoOptions vo;
    vo.stream_nice = want;
    WebRtcSender sender(vo, [&](const std::string& v, const std::string& j) { box.add(v, j); });
    ASSERT_TRUE(sender.handle("v1", hello_json(false)));
    ViewerInfo seen;
    for (int i = 0; i < 150 && seen.encoder_tid == 0; ++i) {
      sender.push_frame(test_image(640, 480, i), i * 33'000'000LL);
      std::this_thread::sleep_for(20ms);
      const auto s = sender.stats();
      if (!s.viewers.empty()) seen = s.viewers[0];
    }
    ASSERT_NE(seen.encoder_tid, 0) << "no frame reached the encoder";
    // A thread never raises its own priority; 0 means "as the caller".
    const int expect = want > 0 ? std::max(want, caller_nice) : caller_nice;
    EXPECT_EQ(seen.encoder_nice, expect) << "stream_nice " << want;
    EXPECT_EQ(kernel_nice_of(seen.encoder_tid), expect) << "stream_nice " << want;
    EXPECT_EQ(getpriority(PRIO_PROCESS, 0), caller_nice);
    EXPECT_EQ(sender.options().stream_nice, want);
  }
}

TEST(WebRtcBitrate, BacksOffOnLossAndQueuesAndRecoversToTheTarget) {
  BitrateController c(3000, 300);
  EXPECT_EQ(c.update(0.0, 0.010), 3000);  // never above the target
  const int lossy = c.update(0.30, 0.010);
  EXPECT_LT(lossy, 3000);
  EXPECT_GE(lossy, static_cast<int>(3000 * 0.85) - 1);
  for (int i = 0; i < 50; ++i) c.update(0.5, 0.010);
  EXPECT_EQ(c.kbps(), 300);  // never below the floor
  for (int i = 0; i < 100; ++i) c.update(0.0, 0.010);
  EXPECT_EQ(c.kbps(), 3000);
  // Round trip far above the best seen: a queue is building; back off without loss.
  const int queued = c.update(0.0, 0.500);
  EXPECT_LT(queued, 3000);
  // Moderate loss (2..10%) holds the rate.
  EXPECT_EQ(c.update(0.05, 0.010), queued);
}

TEST(WebRtcVideo, ParsesSizes) {
  VideoOptions o;
  parse_video_size("1280x720", "--video", o);
  EXPECT_EQ(o.width, 1280);
  EXPECT_EQ(o.height, 720);
  for (const char* bad : {"720p", "1281x720", "64x48", "4000x3000", "640x480x", ""}) {
    EXPECT_THROW(parse_video_size(bad, "--video", o), std::exception) << bad;
  }
}

}  // namespace
}  // namespace kestrel::comm
