// mapd against a real mosquitto: two agents' object tables in their own frames become one team
// map on kestrel/v1/team/objects; bad input (malformed, oversized, unknown version, the wrong
// kind, an agent outside the team) is rejected and counted without touching the map; the ACL
// keeps agents from writing the team layer.
#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "comm/agent_link.hpp"
#include "comm/mapd.hpp"
#include "comm/station_link.hpp"
#include "comm/topics.hpp"
#include "core/error.hpp"
#include "tests/comm/local_broker.hpp"

namespace kestrel::comm {
namespace {

using namespace std::chrono_literals;

MqttOptions opts(const test::LocalBroker& b, const std::string& user, const std::string& pass) {
  MqttOptions o;
  o.port = b.port();
  o.username = user;
  o.password = pass;
  o.client_id = user;
  return o;
}

ObjectInfo obj(std::uint32_t id, const std::string& label, std::array<double, 3> c,
               std::array<double, 3> size, std::uint32_t obs) {
  ObjectInfo o;
  o.id = id;
  o.label = label;
  o.center = c;
  o.size = size;
  o.observations = obs;
  return o;
}

// Spins mapd on this thread until the station sees a team map that satisfies pred.
bool spin_until(Mapd& mapd, StationLink& st,
                const std::function<bool(const std::map<std::uint32_t, ObjectInfo>&)>& pred,
                std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    mapd.spin_once();
    if (auto team = st.agent(kTeamName); team && pred(team->objects)) return true;
    std::this_thread::sleep_for(20ms);
  }
  return false;
}

TEST(Mapd, MergesAgentsRejectsBadInputAndOwnsTheTeamLayer) {
  test::LocalBroker broker(
      {{"station", "st"}, {"mapd", "md"}, {"a1", "p1"}, {"a2", "p2"}, {"intruder", "pi"}});
  MapdOptions mo;
  mo.mqtt = opts(broker, "mapd", "md");
  mo.agents = {"a1", "a2"};
  // a2's configured start is 0.3 m and 3 degrees off its truth (10, 0, 90 degrees): mapd must
  // take it onto the shared chair and table.
  mo.starts = {{"a1", Pose4{}}, {"a2", Pose4{{10.3, -0.2, 0}, M_PI / 2 + 0.05}}};
  mo.publish_period_s = 0.1;
  Mapd mapd(mo);
  mapd.start();
  ASSERT_TRUE(mapd.wait_connected(5s));
  StationLinkOptions so;
  so.mqtt = opts(broker, "station", "st");
  StationLink st(so);
  st.start();
  ASSERT_TRUE(st.wait_connected(5s));

  auto link = [&](const std::string& id, const std::string& pw) {
    AgentLinkOptions ao;
    ao.id = id;
    ao.mqtt = opts(broker, id, pw);
    auto l = std::make_unique<AgentLink>(ao, nullptr);
    l->start();
    EXPECT_TRUE(l->wait_connected(5s));
    return l;
  };
  auto a1 = link("a1", "p1");
  auto a2 = link("a2", "p2");
  // World: chair (1, 0), table (3, 1), bench (2, -2) seen by a1 from the origin; a2 stands at
  // (10, 0) facing +y and sees the chair, the table and a tv at (8, 4).
  ObjectsMsg m1;
  m1.objects = {obj(1, "chair", {1, 0, 0.5}, {0.5, 0.5, 0.9}, 8),
                obj(2, "dining table", {3, 1, 0.4}, {1.2, 0.8, 0.75}, 6),
                obj(3, "bench", {2, -2, 0.25}, {2, 0.5, 0.5}, 4)};
  a1->publish(m1);
  auto to_a2 = [](double x, double y) {  // p_a2 = Rz(-90 deg) (p - (10, 0))
    return std::array<double, 2>{y, -(x - 10)};
  };
  ObjectsMsg m2;
  const auto c = to_a2(1, 0), t = to_a2(3, 1), tv = to_a2(8, 4);
  m2.objects = {obj(7, "chair", {c[0], c[1], 0.5}, {0.5, 0.5, 0.9}, 4),
                obj(8, "dining table", {t[0], t[1], 0.4}, {1.2, 0.8, 0.75}, 6),
                obj(9, "tv", {tv[0], tv[1], 1.0}, {1.0, 0.1, 0.6}, 5)};
  a2->publish(m2);

  ASSERT_TRUE(spin_until(
      mapd, st, [](const auto& objs) { return objs.size() == 4; }, 10s));
  std::map<std::string, ObjectInfo> by_label;
  const auto team = st.agent(kTeamName);  // a copy: the loop must not outlive it
  for (const auto& [id, o] : team->objects) by_label[o.label] = o;
  ASSERT_EQ(by_label.size(), 4u);  // no label twice: chair and table merged across agents
  EXPECT_EQ(by_label["chair"].agents, (std::vector<std::string>{"a1", "a2"}));
  EXPECT_EQ(by_label["tv"].agents, std::vector<std::string>{"a2"});
  EXPECT_EQ(by_label["chair"].observations, 12u);
  EXPECT_NEAR(by_label["tv"].center[0], 8.0, 0.01);  // a2's frame refined onto the team's
  EXPECT_NEAR(by_label["tv"].center[1], 4.0, 0.01);
  EXPECT_NEAR(by_label["chair"].center[0], 1.0, 0.01);
  EXPECT_EQ(mapd.last().frames.at("a2").matched, 2);
  EXPECT_EQ(mapd.counts().rejected(), 0u);

  // Bad input, all on a1's objects topic (the station may write anywhere), and a stranger.
  MqttClient bad(opts(broker, "station", "st"));
  bad.start();
  ASSERT_TRUE(bad.wait_connected(5s));
  const std::string topic = topic_of("a1", "objects");
  auto text = [](const std::string& s) { return std::vector<std::uint8_t>(s.begin(), s.end()); };
  bad.publish(topic, {0xa1, 0x61, 0x76, 0xff}, 1);  // broken CBOR
  bad.publish(topic, text(R"({"v":2,"k":"objects","t":1,"full":true,"o":[],"rm":[]})"), 1);
  bad.publish(topic, std::vector<std::uint8_t>(kMaxMessageBytes + 100, '{'), 1);
  bad.publish(topic, text(R"({"v":1,"k":"objects","t":1,"full":true,"rm":[],"o":[{"id":1}]})"), 1);
  bad.publish(topic, encode(PoseMsg{}), 1);  // decodes, but is no objects message
  auto intruder = link("intruder", "pi");
  ObjectsMsg fake;
  fake.full = true;
  fake.objects = {obj(1, "car", {0, 0, 0}, {4, 2, 1.5}, 50)};
  intruder->publish(fake);
  // The ACL: an agent writing the team layer is refused by the broker (PUBACK 0x87).
  const auto refused_before = a1->client().stats().refused;
  ObjectsMsg forged;
  forged.full = true;
  a1->client().publish(topic_of(kTeamName, "objects"), encode(forged), 1, true);

  const auto end = std::chrono::steady_clock::now() + 10s;
  while (std::chrono::steady_clock::now() < end &&
         (mapd.counts().rejected() < 7 || a1->client().stats().refused == refused_before)) {
    mapd.spin_once();
    std::this_thread::sleep_for(20ms);
  }
  const MapdCounts counts = mapd.counts();
  EXPECT_EQ(counts.decode.malformed, 1u);
  EXPECT_EQ(counts.decode.unknown_version, 1u);
  EXPECT_EQ(counts.decode.oversized, 1u);
  EXPECT_EQ(counts.decode.bad_field, 1u);
  EXPECT_EQ(counts.wrong_kind, 1u);
  EXPECT_EQ(counts.unknown_agent, 2u);  // its link's snapshot on connect, then the car
  EXPECT_EQ(a1->client().stats().refused, refused_before + 1);
  mapd.spin_once(true);
  std::this_thread::sleep_for(300ms);
  // The map is what it was: a1's table untouched, no car, not the forged empty snapshot.
  EXPECT_EQ(mapd.last().objects.size(), 4u);
  EXPECT_EQ(st.agent(kTeamName)->objects.size(), 4u);

  // A delta that removes a1's bench shrinks the team map.
  ObjectsMsg rm;
  rm.removed = {3};
  a1->publish(rm);
  EXPECT_TRUE(spin_until(
      mapd, st, [](const auto& objs) { return objs.size() == 3; }, 10s));
}

// An agent may not be named after the team layer.
TEST(Mapd, TeamIsNoAgentName) {
  AgentLinkOptions ao;
  ao.id = kTeamName;
  EXPECT_THROW(AgentLink(ao, nullptr), Error);
}

}  // namespace
}  // namespace kestrel::comm
