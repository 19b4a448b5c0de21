// Schema codec: round trips in both encodings, and rejection (never a crash) of bad input.
#include <gtest/gtest.h>

#include <rapidcheck/gtest.h>
#include <algorithm>

#include <nlohmann/json.hpp>

#include "comm/codec.hpp"

namespace kestrel::comm {
namespace {

std::vector<std::uint8_t> bytes_of(const std::string& s) { return {s.begin(), s.end()}; }

Decoder quiet() {
  return Decoder([](const std::string&) {});
}

TEST(Schema, PoseRoundTripsWithinQuantization) {
  PoseMsg p;
  p.t = 1341846313592026000;
  p.p = {1.23456789, -20.5, 3.0001};
  p.q = {0.1, 0.2, 0.3, 0.927361849549570};
  p.state = 1;
  p.seq = 77;
  for (Encoding e : {Encoding::kCbor, Encoding::kJson}) {
    auto d = quiet();
    auto m = d.decode(encode(p, e));
    ASSERT_TRUE(m);
    const auto& q = std::get<PoseMsg>(*m);
    EXPECT_EQ(q.t, p.t);
    EXPECT_EQ(q.seq, 77u);
    EXPECT_EQ(q.state, 1);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(q.p[i], p.p[i], 1e-4);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(q.q[i], p.q[i], 1e-6);
  }
}

TEST(Schema, EveryKindRoundTrips) {
  ObjectsMsg objects;
  objects.t = 5;
  objects.objects.push_back({3, "chair", {1, 2, 0.5}, {0.5, 0.5, 1}, 0.25, 12, {}});
  objects.removed = {9};
  objects.seq = kMaxObjectsSeq;  // the largest the page compares exactly
  GridDeltaMsg grid;
  grid.seq = 4;
  grid.base_seq = 3;
  grid.width = 10;
  grid.height = 20;
  grid.origin = {-1, -2};
  grid.runs_zlib = {1, 2, 3, 250};
  CommandMsg goal{"c1", 7, CommandKind::kGoal, {1.5, -2.5, 0.5}, 0, 0, ""};
  CommandMsg teleop{"c2", 8, CommandKind::kTeleop, {}, 0.4, -0.2, ""};
  CommandMsg save{"c3", 9, CommandKind::kSaveMap, {}, 0, 0, "/tmp/map"};
  const std::vector<Message> all = {PoseMsg{},
                                    StatusMsg{1, true, "ok", "uav", 29.9, 0.8, 0.95, 100, 2, 1},
                                    DetectionsMsg{2, {{"person", 3}, {"dynamic", 1}}, 40},
                                    objects,
                                    grid,
                                    PathMsg{3, "c1", {{0, 0}, {1, 1.5}}, false},
                                    goal,
                                    teleop,
                                    save,
                                    CommandMsg{"c4", 1, CommandKind::kPause, {}, 0, 0, ""},
                                    AckMsg{"c1", 10, AckResult::kDone, "path of 12 cells"},
                                    PingMsg{5, 123},
                                    PongMsg{5, 123, 456, 789}};
  for (Encoding e : {Encoding::kCbor, Encoding::kJson}) {
    for (const Message& m : all) {
      auto d = quiet();
      auto out = d.decode(encode(m, e));
      ASSERT_TRUE(out) << stream_of(m);
      EXPECT_EQ(out->index(), m.index());
      // Encoding the decoded message again gives the same bytes: nothing was lost or invented.
      EXPECT_EQ(encode(*out, e), encode(m, e)) << stream_of(m);
    }
  }
  auto d = quiet();
  const auto g = std::get<GridDeltaMsg>(*d.decode(encode(grid)));
  EXPECT_EQ(g.runs_zlib, grid.runs_zlib);
  const auto c = std::get<CommandMsg>(*d.decode(encode(save)));
  EXPECT_EQ(c.path, "/tmp/map");
  EXPECT_EQ(c.kind, CommandKind::kSaveMap);
}

TEST(Schema, CborIsSmallerThanJsonForPose) {
  PoseMsg p;
  p.t = 1700000000123456789;
  p.p = {12.3456, -3.21, 1.5};
  p.q = {0.01, -0.02, 0.7, 0.71};
  p.seq = 1000;
  EXPECT_LT(encode(p, Encoding::kCbor).size(), encode(p, Encoding::kJson).size());
}

TEST(Schema, RejectsAndCountsBadInput) {
  std::vector<std::string> log;
  Decoder d([&](const std::string& line) { log.push_back(line); });
  EXPECT_FALSE(d.decode(std::vector<std::uint8_t>{}, "t/empty"));
  EXPECT_FALSE(d.decode(bytes_of("not json at all"), "t/garbage"));
  EXPECT_FALSE(d.decode(bytes_of("{\"v\":1,\"k\":\"pose\""), "t/truncated"));
  auto cbor = encode(PoseMsg{});
  cbor.resize(cbor.size() / 2);
  EXPECT_FALSE(d.decode(cbor, "t/truncated-cbor"));
  EXPECT_FALSE(d.decode(bytes_of(R"({"v":2,"k":"pose"})"), "t/v2"));
  EXPECT_FALSE(d.decode(bytes_of(R"({"v":1,"k":"teleport"})"), "t/kind"));
  EXPECT_FALSE(d.decode(bytes_of(R"({"v":1,"k":"pose","t":1,"p":[1,2],"q":[0,0,0,1],"s":0,"n":1})"),
                        "t/short-array"));
  EXPECT_FALSE(d.decode(bytes_of(R"({"v":1,"k":"cmd","id":"x","t":1,"c":"fly"})"), "t/cmd"));
  EXPECT_FALSE(d.decode(bytes_of(R"({"v":1,"k":"ack","id":5,"t":1,"r":"done"})"), "t/type"));
  EXPECT_FALSE(
      d.decode(bytes_of(R"({"v":1,"k":"pose","t":-5,"p":[1,2,3],"q":[0,0,0,1],"s":0,"n":1})"),
               "t/negative-stamp"));
  EXPECT_FALSE(d.decode(bytes_of(R"({"v":1,"k":"objects","t":1,"n":9007199254740992,"full":true,)"
                                 R"("o":[],"rm":[]})"),
                        "t/objects-seq-beyond-2^53"));
  EXPECT_FALSE(d.decode(bytes_of("[1,2,3]"), "t/array"));
  std::vector<std::uint8_t> huge(kMaxMessageBytes + 1, '{');
  EXPECT_FALSE(d.decode(huge, "t/huge"));
  const DecodeCounts c = d.counts();
  EXPECT_EQ(c.oversized, 1u);
  EXPECT_EQ(c.unknown_version, 1u);
  EXPECT_EQ(c.unknown_kind, 1u);
  EXPECT_EQ(c.malformed, 5u);  // empty, garbage, truncated JSON, truncated CBOR, not a map
  EXPECT_EQ(c.bad_field, 5u);
  EXPECT_EQ(c.rejected(), 13u);
  EXPECT_EQ(c.ok, 0u);
  ASSERT_FALSE(log.empty());
  EXPECT_NE(log.front().find("t/empty"), std::string::npos);
  // A valid message still decodes after all that.
  EXPECT_TRUE(d.decode(encode(PoseMsg{})));
}

// Found by fuzz/telemetry_codec_fuzz.cpp: CBOR text that is not UTF-8 decoded, then threw when
// the message was written as JSON.
TEST(Schema, RejectsTextThatIsNotUtf8) {
  auto d = quiet();
  StatusMsg s{1, true, "ok", "uav", 29.9, 0.8, 0.95, 100, 2, 1};
  std::vector<std::uint8_t> cbor = encode(s);
  const std::vector<std::uint8_t> ok = {'o', 'k'};
  const auto at = std::search(cbor.begin(), cbor.end(), ok.begin(), ok.end());
  ASSERT_NE(at, cbor.end());
  at[0] = 0xc3;  // a lead byte followed by 'k', which is no continuation byte
  EXPECT_FALSE(d.decode(cbor, "t/utf8"));
  EXPECT_EQ(d.counts().bad_field, 1u);
  StatusMsg accented = s;
  accented.state = "d\xc3\xa9j\xc3\xa0";  // "déjà", valid UTF-8
  EXPECT_TRUE(d.decode(encode(accented)));
  DetectionsMsg det{2, {{"person", 3}}, 1};
  std::vector<std::uint8_t> dcbor = encode(det);
  const std::vector<std::uint8_t> person = {'p', 'e', 'r', 's', 'o', 'n'};
  const auto p = std::search(dcbor.begin(), dcbor.end(), person.begin(), person.end());
  ASSERT_NE(p, dcbor.end());
  p[0] = 0xff;
  EXPECT_FALSE(d.decode(dcbor, "t/utf8-label"));
}

RC_GTEST_PROP(Schema, RandomBytesNeverCrash, (const std::vector<std::uint8_t>& junk)) {
  auto d = quiet();
  auto m = d.decode(junk);
  RC_ASSERT(d.counts().ok + d.counts().rejected() == 1u);
  if (m) RC_ASSERT(d.counts().ok == 1u);
}

RC_GTEST_PROP(Schema, MutatedMessagesNeverCrash, (std::size_t at, std::uint8_t value)) {
  StatusMsg s{1, true, "ok", "uav", 29.9, 0.8, 0.95, 100, 2, 1};
  for (Encoding e : {Encoding::kCbor, Encoding::kJson}) {
    auto bytes = encode(s, e);
    bytes[at % bytes.size()] = value;
    auto d = quiet();
    d.decode(bytes);
    RC_ASSERT(d.counts().ok + d.counts().rejected() == 1u);
  }
}

}  // namespace
}  // namespace kestrel::comm
