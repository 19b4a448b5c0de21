// The team map's parts without a broker: object deltas, the schema's `agents` field, start-pose
// parsing, frame refinement from shared objects and merging without duplicates.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "comm/codec.hpp"
#include "comm/object_telemetry.hpp"
#include "comm/team_map.hpp"
#include "core/error.hpp"

namespace kestrel::comm {
namespace {

ObjectInfo obj(std::uint32_t id, const std::string& label, std::array<double, 3> c,
               std::array<double, 3> size = {0.6, 0.6, 1.0}, std::uint32_t obs = 5) {
  ObjectInfo o;
  o.id = id;
  o.label = label;
  o.center = c;
  o.size = size;
  o.observations = obs;
  return o;
}

TEST(ObjectDelta, SendsOnlyChangesAndRemovals) {
  std::map<std::uint32_t, ObjectInfo> sent;
  sent[1] = obj(1, "chair", {1, 2, 0.5});
  sent[2] = obj(2, "bench", {3, 2, 0.3});
  std::vector<ObjectInfo> now = {obj(1, "chair", {1.01, 2, 0.5}),  // 1 cm: not worth a message
                                 obj(3, "tv", {0, 0, 1})};
  ObjectsMsg d = object_delta(sent, now);
  ASSERT_EQ(d.objects.size(), 1u);
  EXPECT_EQ(d.objects[0].id, 3u);
  EXPECT_EQ(d.removed, std::vector<std::uint32_t>{2});
  now[0].center[0] = 1.1;  // 10 cm
  now[0].observations = 6;
  d = object_delta(sent, now);
  EXPECT_EQ(d.objects.size(), 2u);
  sent[1] = now[0];
  sent[3] = now[1];
  sent.erase(2);
  d = object_delta(sent, now);
  EXPECT_TRUE(d.objects.empty() && d.removed.empty());
}

TEST(TeamSchema, AgentsFieldRoundTripsAndIsChecked) {
  ObjectsMsg m;
  m.full = true;
  m.objects.push_back(obj(7, "chair", {1, 2, 3}));
  m.objects[0].agents = {"uav1", "ugv2"};
  for (Encoding e : {Encoding::kCbor, Encoding::kJson}) {
    Decoder dec([](const std::string&) {});
    auto back = dec.decode(encode(m, e));
    ASSERT_TRUE(back);
    const auto& o = std::get<ObjectsMsg>(*back).objects.at(0);
    EXPECT_EQ(o.agents, (std::vector<std::string>{"uav1", "ugv2"}));
  }
  // An agent's own message carries no `a` at all.
  const auto plain = encode(ObjectsMsg{0, true, {obj(1, "tv", {0, 0, 0})}, {}}, Encoding::kJson);
  EXPECT_EQ(std::string(plain.begin(), plain.end()).find("\"a\""), std::string::npos);
  Decoder dec([](const std::string&) {});
  const std::string bad =
      R"({"v":1,"k":"objects","t":1,"full":true,"rm":[],)"
      R"("o":[{"id":1,"l":"tv","c":[0,0,0],"s":[1,1,1],"y":0,"o":1,"a":["bad/id"]}]})";
  EXPECT_FALSE(
      dec.decode(std::span(reinterpret_cast<const std::uint8_t*>(bad.data()), bad.size())));
  EXPECT_EQ(dec.counts().bad_field, 1u);
}

TEST(TeamMap, ParsesStartPoses) {
  const auto [name, p] = parse_start_pose("uav1:1.5,-2,0.3,90", "--start");
  EXPECT_EQ(name, "uav1");
  EXPECT_DOUBLE_EQ(p.t[0], 1.5);
  EXPECT_DOUBLE_EQ(p.t[1], -2);
  EXPECT_NEAR(p.yaw, M_PI / 2, 1e-12);
  EXPECT_THROW(parse_start_pose("uav1:1,2,3", "--start"), Error);
  EXPECT_THROW(parse_start_pose("uav1:1,2,x,4", "--start"), Error);
  EXPECT_THROW(parse_start_pose("1,2,3,4", "--start"), Error);
}

// A world of objects seen by three agents, each in its own frame with centimetre noise; the
// configured starts are off by up to 0.5 m and 6 degrees. The refined frames must recover the
// truth and the merged map must hold every world object once.
TEST(TeamMap, RefinesFramesFromSharedObjectsAndMergesWithoutDuplicates) {
  const std::vector<ObjectInfo> world = {
      obj(0, "bench", {0, -6.8, 0.25}, {2.0, 0.5, 0.5}),
      obj(0, "potted plant", {6.5, 6.5, 0.6}, {0.6, 0.6, 1.2}),
      obj(0, "potted plant", {-6.5, -6.5, 0.6}, {0.6, 0.6, 1.2}),
      obj(0, "dining table", {-1.5, 6.8, 0.375}, {1.2, 0.8, 0.75}),
      obj(0, "chair", {-1.5, 6.2, 0.475}, {0.5, 0.5, 0.95}),
      obj(0, "suitcase", {6.0, -6.0, 0.35}, {0.45, 0.25, 0.7}),
      obj(0, "dining table", {6.8, 1.5, 0.375}, {0.8, 1.2, 0.75})};
  struct Agent {
    std::string id;
    Pose4 truth;  // T_team_agent
    Pose4 error;  // what the operator's start is off by
    std::vector<std::size_t> sees;
  };
  const std::vector<Agent> agents = {
      {"a1", {{-4.5, -4.5, 1.5}, 0.0}, {{0, 0, 0}, 0}, {0, 2, 5, 6}},
      {"a2", {{4.5, -4.5, 1.5}, M_PI / 2}, {{0.4, -0.3, 0.05}, 0.1}, {5, 6, 1, 3}},
      {"a3", {{4.5, 4.5, 1.5}, M_PI}, {{-0.3, 0.4, 0}, -0.08}, {1, 3, 4, 2, 0}}};
  TeamMap map;
  std::mt19937 rng(4);
  std::normal_distribution<double> noise(0.0, 0.03);
  for (const Agent& a : agents) {
    map.set_start(a.id, a.truth.then(a.error));
    ObjectsMsg m;
    m.full = true;
    // Agent frame: p_agent = Rz(-yaw) (p_team - t).
    const double c = std::cos(a.truth.yaw), s = std::sin(a.truth.yaw);
    for (std::size_t k : a.sees) {
      ObjectInfo o = world[k];
      o.id = static_cast<std::uint32_t>(100 + k);
      const double dx = o.center[0] - a.truth.t[0], dy = o.center[1] - a.truth.t[1];
      o.center = {c * dx + s * dy + noise(rng), -s * dx + c * dy + noise(rng),
                  o.center[2] - a.truth.t[2] + noise(rng)};
      m.objects.push_back(o);
    }
    map.apply(a.id, m);
  }
  const TeamMapResult r = map.build();
  ASSERT_EQ(r.frames.size(), 3u);
  EXPECT_TRUE(r.frames.at("a1").reference);
  for (const Agent& a : agents) {
    const AgentFrame& f = r.frames.at(a.id);
    EXPECT_NEAR(f.T_team_agent.t[0], a.truth.t[0], 0.15) << a.id;
    EXPECT_NEAR(f.T_team_agent.t[1], a.truth.t[1], 0.15) << a.id;
    EXPECT_NEAR(std::remainder(f.T_team_agent.yaw - a.truth.yaw, 2 * M_PI), 0.0, 0.03) << a.id;
    if (!f.reference) {
      EXPECT_GE(f.matched, 2) << a.id;
    }
  }
  ASSERT_EQ(r.objects.size(), world.size());
  for (const ObjectInfo& w : world) {
    int found = 0;
    for (const ObjectInfo& o : r.objects) {
      const double d = std::hypot(o.center[0] - w.center[0], o.center[1] - w.center[1]);
      if (o.label == w.label && d < 0.2) ++found;
    }
    EXPECT_EQ(found, 1) << w.label << " at " << w.center[0] << "," << w.center[1];
  }
  for (const ObjectInfo& o : r.objects) EXPECT_FALSE(o.agents.empty());

  // Ids are stable when an agent's table changes a little, and removal shrinks the map.
  std::map<std::string, std::uint32_t> ids;
  for (const auto& o : r.objects) ids[o.label + std::to_string(std::lround(o.center[0]))] = o.id;
  ObjectsMsg nudge;
  ObjectInfo moved = obj(105, "suitcase", {0, 0, 0});
  {
    const double c = std::cos(agents[0].truth.yaw), s = std::sin(agents[0].truth.yaw);
    const double dx = 6.05 - agents[0].truth.t[0], dy = -6.0 - agents[0].truth.t[1];
    moved.center = {c * dx + s * dy, -s * dx + c * dy, 0.35 - 1.5};
    moved.size = world[5].size;
  }
  nudge.objects.push_back(moved);
  map.apply("a1", nudge);
  const TeamMapResult r2 = map.build();
  ASSERT_EQ(r2.objects.size(), world.size());
  for (const auto& o : r2.objects) {
    EXPECT_EQ(ids.at(o.label + std::to_string(std::lround(o.center[0]))), o.id) << o.label;
  }
}

// A delta that the agent's client re-sent after a broker crash arrives behind the snapshot that
// followed it: applied, it would bring back the chair the snapshot no longer holds.
TEST(TeamMap, IgnoresObjectsMessagesOlderThanOneApplied) {
  TeamMap map;
  map.set_start("a", {});
  ObjectsMsg added;
  added.objects = {obj(1, "chair", {1, 2, 0.5})};
  added.seq = 100;
  ObjectsMsg snapshot;
  snapshot.full = true;
  snapshot.objects = {obj(2, "tv", {0, 4, 1})};
  snapshot.seq = 102;
  EXPECT_TRUE(map.apply("a", added));
  EXPECT_TRUE(map.apply("a", snapshot));
  EXPECT_FALSE(map.apply("a", added));     // late re-send
  EXPECT_FALSE(map.apply("a", snapshot));  // duplicate
  EXPECT_EQ(map.agent_objects("a"), 1u);
  EXPECT_EQ(map.build().objects.at(0).label, "tv");
  // Unnumbered messages (seq 0) are always applied; another agent's numbers are its own.
  ObjectsMsg plain = added;
  plain.seq = 0;
  EXPECT_TRUE(map.apply("a", plain));
  EXPECT_EQ(map.agent_objects("a"), 2u);
  EXPECT_TRUE(map.apply("b", added));
}

TEST(ObjectsSeq, ARestartedSenderGoesOnAboveItsLastRun) {
  const std::int64_t start = 1'796'000'000'000'000'000;  // 2026, in ns
  const std::uint64_t first = first_objects_seq(start);
  // 100,000 messages a second for a whole day still stay below the next run's first number.
  EXPECT_LT(first + 100'000ULL * 86'400, first_objects_seq(start + 86'400'000'000'000LL));
  EXPECT_LE(first, kMaxObjectsSeq);
  EXPECT_GT(first_objects_seq(0), 0u);
}

// Two objects of one label that one agent keeps apart stay two, even when close; and a
// start pose that is badly wrong is not "corrected" onto a wrong match beyond the bounds.
TEST(TeamMap, KeepsAnAgentsOwnObjectsApartAndBoundsCorrections) {
  TeamMap map;
  map.set_start("a", {});
  map.set_start("b", {{0, 0, 0}, 0});
  ObjectsMsg ma;
  ma.full = true;
  ma.objects = {obj(1, "chair", {0, 0, 0.5}, {0.5, 0.5, 0.9}),
                obj(2, "chair", {0.3, 0, 0.5}, {0.5, 0.5, 0.9})};
  map.apply("a", ma);
  ObjectsMsg mb;
  mb.full = true;
  mb.objects = {obj(1, "chair", {0.02, 0, 0.5}, {0.5, 0.5, 0.9}),
                obj(2, "tv", {20, 0, 1}, {1, 0.1, 0.6})};
  map.apply("b", mb);
  TeamMapResult r = map.build();
  EXPECT_EQ(r.objects.size(), 3u);  // two chairs (one seen by both) and the tv
  EXPECT_EQ(r.merged, 1);

  // b's start is configured 3 m off. Even with a candidate gate wide enough to pair the chairs,
  // the 3 m correction exceeds max_shift_m: the prior stands and the map says so (0 matched).
  TeamMapOptions wide;
  wide.match_gate_m = 5.0;
  TeamMap far(wide);
  far.set_start("a", {});
  far.set_start("b", {{3, 0, 0}, 0});
  far.apply("a", ma);
  far.apply("b", mb);
  r = far.build();
  EXPECT_EQ(r.frames.at("b").matched, 0);
  EXPECT_DOUBLE_EQ(r.frames.at("b").T_team_agent.t[0], 3.0);
  // Within the bounds the same match is taken: 1.5 m off is corrected onto the nearer chair.
  TeamMap near(wide);
  near.set_start("a", {});
  near.set_start("b", {{1.5, 0, 0}, 0});
  near.apply("a", ma);
  near.apply("b", mb);
  r = near.build();
  EXPECT_EQ(r.frames.at("b").matched, 1);
  EXPECT_NEAR(r.frames.at("b").T_team_agent.t[0], 0.28, 1e-6);  // onto the chair at 0.3
}

}  // namespace
}  // namespace kestrel::comm
