// Against a real mosquitto (scripts/mosquitto/start_broker.sh) on free loopback ports, with
// passwords and the ACL: order of poses, exactly-once commands across a broker crash, no lost
// object update, last will, refused credentials and topics, counted bad messages.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <map>
#include <thread>

#include "comm/agent_link.hpp"
#include "comm/station_link.hpp"
#include "comm/topics.hpp"
#include "tests/comm/local_broker.hpp"

namespace kestrel::comm {
namespace {

using namespace std::chrono_literals;
using test::LocalBroker;

const std::vector<std::pair<std::string, std::string>> kUsers = {
    {"station", "st-secret"}, {"a1", "pw-a1"}, {"a2", "pw-a2"}};

MqttOptions opts(const LocalBroker& b, const std::string& user, const std::string& pass) {
  MqttOptions o;
  o.port = b.port();
  o.client_id = user;
  o.username = user;
  o.password = pass;
  o.keepalive_s = 5;
  o.reconnect_min_s = 1;
  o.reconnect_max_s = 1;
  return o;
}

std::unique_ptr<StationLink> station(const LocalBroker& b) {
  StationLinkOptions so;
  so.mqtt = opts(b, "station", "st-secret");
  so.retry = 500ms;
  auto s = std::make_unique<StationLink>(so);
  s->start();
  EXPECT_TRUE(s->wait_connected(5s));
  return s;
}

std::unique_ptr<AgentLink> agent(const LocalBroker& b, const std::string& id,
                                 const std::string& pass, CommandHandler h = {}) {
  AgentLinkOptions ao;
  ao.id = id;
  ao.role = "ugv";
  ao.mqtt = opts(b, id, pass);
  auto a = std::make_unique<AgentLink>(ao, std::move(h));
  a->start();
  EXPECT_TRUE(a->wait_connected(5s));
  return a;
}

bool heard_status(const std::map<std::string, AgentView>& m, const std::string& id, bool online) {
  auto it = m.find(id);
  return it != m.end() && it->second.have_status && it->second.status.online == online;
}

TEST(MqttIntegration, PosesArriveInOrder) {
  LocalBroker broker(kUsers);
  auto st = station(broker);
  auto a = agent(broker, "a1", "pw-a1");
  const int n = 300;
  for (int i = 1; i <= n; ++i) {
    PoseMsg p;
    p.t = i * 33'333'333LL;
    p.p = {0.01 * i, 0, 0};
    p.seq = static_cast<std::uint32_t>(i);
    a->publish(p);
    std::this_thread::sleep_for(1ms);
  }
  ASSERT_TRUE(
      st->wait_for([&](const auto& m) { return m.count("a1") && m.at("a1").pose.seq == n; }, 5s));
  const AgentView v = *st->agent("a1");
  EXPECT_EQ(v.poses, static_cast<std::uint64_t>(n));
  EXPECT_EQ(v.poses_out_of_order, 0u);
  EXPECT_EQ(v.poses_missed, 0u);
  EXPECT_NEAR(v.pose.p[0], 0.01 * n, 1e-4);
}

TEST(MqttIntegration, CommandsExecutedExactlyOnceAcrossBrokerCrash) {
  LocalBroker broker(kUsers);
  auto st = station(broker);
  std::mutex mu;
  std::map<std::string, int> executed;
  auto a = agent(broker, "a1", "pw-a1", [&](const CommandMsg& c) {
    std::lock_guard lock(mu);
    ++executed[c.id];
    return AckMsg{c.id, 0, AckResult::kDone, ""};
  });
  a->publish(StatusMsg{1, true, "ok", "", 30, 0.5, 1, 0, 0, 0});
  ASSERT_TRUE(st->wait_for([](const auto& m) { return heard_status(m, "a1", true); }, 5s));

  std::vector<std::string> ids;
  for (int i = 0; i < 10; ++i) {
    CommandMsg c;
    c.kind = i % 2 ? CommandKind::kPause : CommandKind::kResume;
    auto id = st->send_command("a1", c);
    ASSERT_TRUE(id);
    ids.push_back(*id);
    if (i == 4) {
      broker.stop(SIGKILL);  // a crash: no clean shutdown, some commands in flight
      std::this_thread::sleep_for(300ms);
    }
  }
  broker.start();
  for (const auto& id : ids) {
    auto ack = st->wait_ack(id, 15s);
    ASSERT_TRUE(ack) << id << "\n" << broker.log();
  }
  std::this_thread::sleep_for(1500ms);  // let any late re-send arrive: it must not execute
  std::lock_guard lock(mu);
  EXPECT_EQ(executed.size(), ids.size());
  for (const auto& id : ids) EXPECT_EQ(executed[id], 1) << id;
  const auto sc = st->counts();
  std::printf("commands %llu, re-sends %llu, agent duplicates suppressed %llu\n",
              static_cast<unsigned long long>(sc.commands_sent),
              static_cast<unsigned long long>(sc.command_resends),
              static_cast<unsigned long long>(a->counts().commands_duplicate));
}

TEST(MqttIntegration, ObjectUpdatesSurviveBrokerRestart) {
  LocalBroker broker(kUsers);
  auto st = station(broker);
  auto a = agent(broker, "a1", "pw-a1");
  ObjectsMsg first;
  first.objects.push_back({1, "chair", {1, 2, 0}, {0.5, 0.5, 1}, 0, 3, {}});
  a->publish(first);
  ASSERT_TRUE(
      st->wait_for([](const auto& m) { return m.count("a1") && m.at("a1").objects.count(1); }, 5s));
  broker.stop(SIGKILL);
  ObjectsMsg during;  // published while the broker is down
  during.objects.push_back({2, "potted plant", {3, 1, 0}, {0.4, 0.4, 0.8}, 0, 5, {}});
  during.removed.push_back(1);
  a->publish(during);
  ObjectsMsg again;
  again.objects.push_back({3, "tv", {0, 4, 1}, {1, 0.1, 0.6}, 1.57, 2, {}});
  a->publish(again);
  broker.start();
  ASSERT_TRUE(st->wait_for(
      [](const auto& m) {
        if (!m.count("a1")) return false;
        const auto& o = m.at("a1").objects;
        return o.size() == 2 && o.count(2) && o.count(3);
      },
      10s))
      << broker.log();
  // What the client re-sends after the crash may arrive behind the reconnect's snapshot (the
  // delta that added object 1 and was never acknowledged): it must not bring object 1 back.
  for (int i = 0; i < 100 && a->client().outbox_size() > 0; ++i) std::this_thread::sleep_for(20ms);
  std::this_thread::sleep_for(300ms);
  const auto view = st->agent("a1");
  ASSERT_TRUE(view);
  EXPECT_EQ(view->objects.size(), 2u);
  EXPECT_EQ(view->objects.count(1), 0u);
  EXPECT_EQ(view->objects.at(3).label, "tv");
}

// The same late re-send, made on purpose: a delta numbered below the snapshot already applied is
// ignored and counted; the next newer delta applies.
TEST(MqttIntegration, LateObjectsDeltaDoesNotUndoANewerSnapshot) {
  LocalBroker broker(kUsers);
  auto st = station(broker);
  MqttOptions ro = opts(broker, "a1", "pw-a1");
  MqttClient raw_agent(ro);
  raw_agent.start();
  ASSERT_TRUE(raw_agent.wait_connected(5s));
  ObjectsMsg snapshot;
  snapshot.full = true;
  snapshot.seq = 10;
  snapshot.objects.push_back({2, "potted plant", {3, 1, 0}, {0.4, 0.4, 0.8}, 0, 5, {}});
  ObjectsMsg late;  // sent before the snapshot, delivered after it
  late.seq = 5;
  late.objects.push_back({1, "chair", {1, 2, 0}, {0.5, 0.5, 1}, 0, 3, {}});
  ObjectsMsg next;
  next.seq = 11;
  next.objects.push_back({3, "tv", {0, 4, 1}, {1, 0.1, 0.6}, 1.57, 2, {}});
  for (const ObjectsMsg& m : {snapshot, late, next}) {
    raw_agent.publish(topic_of("a1", "objects"), encode(m), 1);
  }
  ASSERT_TRUE(
      st->wait_for([](const auto& m) { return m.count("a1") && m.at("a1").objects.count(3); }, 5s));
  const auto view = st->agent("a1");
  EXPECT_EQ(view->objects.size(), 2u);
  EXPECT_EQ(view->objects.count(1), 0u);
  EXPECT_EQ(view->objects_stale, 1u);
  EXPECT_EQ(view->objects_seq, 11u);
}

// A path re-sent late (planned for an older goal) does not replace the newer goal's path.
TEST(MqttIntegration, LatePathDoesNotReplaceANewerGoalsPath) {
  LocalBroker broker(kUsers);
  auto st = station(broker);
  MqttClient raw_agent(opts(broker, "a1", "pw-a1"));
  raw_agent.start();
  ASSERT_TRUE(raw_agent.wait_connected(5s));
  const PathMsg newer{20, "g2", {{0, 0}, {2, 1}}, false};
  const PathMsg older{10, "g1", {{0, 0}, {-3, 4}}, false};
  raw_agent.publish(topic_of("a1", "path"), encode(newer), 1);
  raw_agent.publish(topic_of("a1", "path"), encode(older), 1);
  raw_agent.publish(topic_of("a1", "status"),
                    encode(StatusMsg{1, true, "ok", "ugv", 30, 0.5, 1, 0, 0, 0}),
                    1);  // after both paths on the same connection
  ASSERT_TRUE(st->wait_for([](const auto& m) { return heard_status(m, "a1", true); }, 5s));
  const auto view = st->agent("a1");
  ASSERT_TRUE(view && view->path);
  EXPECT_EQ(view->path->goal_id, "g2");
  EXPECT_EQ(view->paths_stale, 1u);
}

TEST(MqttIntegration, LastWillMarksKilledAgentOffline) {
  LocalBroker broker(kUsers);
  // The agent lives in a child process so that it can really be killed (no DISCONNECT sent).
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    AgentLinkOptions ao;
    ao.id = "a2";
    ao.mqtt = opts(broker, "a2", "pw-a2");
    AgentLink link(ao, {});
    link.start();
    if (!link.wait_connected(5s)) _exit(3);
    for (;;) {
      link.publish(StatusMsg{1, true, "ok", "", 30, 0.5, 1, 0, 0, 0});
      std::this_thread::sleep_for(200ms);
    }
  }
  auto st = station(broker);
  const bool online = st->wait_for([](const auto& m) { return heard_status(m, "a2", true); }, 8s);
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(online) << broker.log();
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(st->wait_for([](const auto& m) { return heard_status(m, "a2", false); }, 5s));
  std::printf(
      "killed agent marked offline after %.0f ms\n",
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  EXPECT_EQ(st->agent("a2")->status.state, "offline");
}

TEST(MqttIntegration, WrongPasswordIsRefused) {
  LocalBroker broker(kUsers);
  MqttClient bad(opts(broker, "a1", "wrong"));
  bad.start();
  EXPECT_FALSE(bad.wait_connected(3s));
  EXPECT_FALSE(bad.connected());
  const int rc = bad.connack_code();
  EXPECT_TRUE(rc == 0x86 || rc == 0x87) << rc;
  MqttClient anonymous(opts(broker, "", ""));
  anonymous.start();
  EXPECT_FALSE(anonymous.wait_connected(3s));
}

TEST(MqttIntegration, PublishingOutsideTheAclIsRefused) {
  LocalBroker broker(kUsers);
  auto st = station(broker);
  MqttClient a1(opts(broker, "a1", "pw-a1"));
  a1.start();
  ASSERT_TRUE(a1.wait_connected(5s));
  // Another agent's stream, and a command: both refused. Then an allowed one as a marker.
  a1.publish(topic_of("a2", "status"), encode(StatusMsg{}), 1);
  CommandMsg c;
  c.id = "forged";
  a1.publish(topic_of("a1", "cmd"), encode(c), 1);
  a1.publish(topic_of("a1", "status"), encode(StatusMsg{}), 1);
  ASSERT_TRUE(st->wait_for([](const auto& m) { return heard_status(m, "a1", true); }, 5s));
  for (int i = 0; i < 50 && a1.outbox_size() > 0; ++i) std::this_thread::sleep_for(20ms);
  EXPECT_EQ(a1.stats().refused, 2u);
  EXPECT_FALSE(st->agent("a2"));
  // The station itself may command; only what it sent shows up (not the forged one).
  EXPECT_FALSE(st->ack("forged"));
}

TEST(MqttIntegration, MalformedAndUnknownVersionsAreCountedNotFatal) {
  LocalBroker broker(kUsers);
  auto st = station(broker);
  std::atomic<int> executed{0};
  auto a = agent(broker, "a1", "pw-a1", [&](const CommandMsg& c) {
    ++executed;
    return AckMsg{c.id, 0, AckResult::kDone, ""};
  });
  MqttOptions ro = opts(broker, "station", "st-secret");
  ro.client_id = "station-raw";  // a second station connection (same user, own client id)
  MqttClient raw_station(ro);
  raw_station.start();
  ASSERT_TRUE(raw_station.wait_connected(5s));
  const std::string junk = "\xff\x00garbage";
  const std::string v9 = R"({"v":9,"k":"pose","t":1,"p":[0,0,0],"q":[0,0,0,1],"s":0,"n":1})";
  // Toward the station (on a2's topics, through the station's own user: ACL allows it).
  raw_station.publish(topic_of("a2", "pose"), {junk.begin(), junk.end()}, 1);
  raw_station.publish(topic_of("a2", "pose"), {v9.begin(), v9.end()}, 1);
  // Toward the agent: a malformed command and an unknown-version command.
  const std::string bad_cmd = R"({"v":1,"k":"cmd","id":"x1","t":1,"c":"self-destruct"})";
  const std::string v2_cmd = R"({"v":2,"k":"cmd","id":"x2","t":1,"c":"pause"})";
  raw_station.publish(topic_of("a1", "cmd"), {bad_cmd.begin(), bad_cmd.end()}, 1);
  raw_station.publish(topic_of("a1", "cmd"), {v2_cmd.begin(), v2_cmd.end()}, 1);
  // A good JSON command (what a browser would send) still works after them.
  const std::string good = R"({"v":1,"k":"cmd","id":"x3","t":1,"c":"pause"})";
  raw_station.publish(topic_of("a1", "cmd"), {good.begin(), good.end()}, 1);
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (std::chrono::steady_clock::now() < deadline &&
         (st->counts().decode.rejected() < 2 || a->counts().decode.rejected() < 2 ||
          executed.load() < 1)) {
    std::this_thread::sleep_for(20ms);
  }
  const auto sd = st->counts().decode;
  const auto ad = a->counts().decode;
  EXPECT_EQ(sd.malformed, 1u);
  EXPECT_EQ(sd.unknown_version, 1u);
  EXPECT_EQ(ad.bad_field, 1u);
  EXPECT_EQ(ad.unknown_version, 1u);
  EXPECT_EQ(executed.load(), 1);
  // Commands for an agent nobody has heard of are refused before they reach the broker.
  EXPECT_FALSE(st->send_command("ghost", CommandMsg{}));
  EXPECT_EQ(st->counts().commands_unknown_agent, 1u);
}

}  // namespace
}  // namespace kestrel::comm
