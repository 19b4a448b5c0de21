// The small parts of the link: topics, duplicate suppression, clock offset.
#include <gtest/gtest.h>

#include "comm/clock_sync.hpp"
#include "comm/command_dedup.hpp"
#include "comm/mqtt_client.hpp"
#include "comm/topics.hpp"
#include "core/error.hpp"

namespace kestrel::comm {
namespace {

TEST(Topics, LayoutAndValidation) {
  EXPECT_EQ(topic_of("uav1", "pose"), "kestrel/v1/uav1/pose");
  auto p = parse_topic("kestrel/v1/uav1/pose");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->agent, "uav1");
  EXPECT_EQ(p->stream, "pose");
  EXPECT_FALSE(parse_topic("kestrel/v2/uav1/pose"));
  EXPECT_FALSE(parse_topic("kestrel/v1/uav1"));
  EXPECT_FALSE(parse_topic("kestrel/v1/uav1/a/b"));
  EXPECT_FALSE(parse_topic("kestrel/v1/u+/pose"));
  EXPECT_TRUE(valid_agent_id("ugv_2-a"));
  EXPECT_FALSE(valid_agent_id("a/b"));
  EXPECT_FALSE(valid_agent_id("#"));
  EXPECT_FALSE(valid_agent_id(""));
}

TEST(CommandDedup, FirstTimeOnlyAndBounded) {
  CommandDedup d(3);
  EXPECT_TRUE(d.first_time("a"));
  EXPECT_FALSE(d.first_time("a"));
  EXPECT_TRUE(d.first_time("b"));
  EXPECT_TRUE(d.first_time("c"));
  EXPECT_TRUE(d.first_time("d"));  // evicts "a"
  EXPECT_EQ(d.size(), 3u);
  EXPECT_FALSE(d.first_time("d"));
  EXPECT_TRUE(d.first_time("a"));
}

TEST(ClockSync, RecoversOffsetAndRoundTrip) {
  // Agent clock 5 ms ahead; 2 ms each way; 1 ms processing on the agent.
  const std::int64_t ms = 1'000'000;
  PongMsg pong{1, 100 * ms, 100 * ms + 2 * ms + 5 * ms, 100 * ms + 3 * ms + 5 * ms};
  const ClockSample s = clock_sample(pong, 100 * ms + 5 * ms);
  EXPECT_EQ(s.rtt_ns, 4 * ms);
  EXPECT_EQ(s.offset_ns, 5 * ms);
  ClockSync sync;
  sync.add(s);
  sync.add({20 * ms, 9 * ms});  // a slow, asymmetric sample does not win
  EXPECT_EQ(sync.offset_ns(), 5 * ms);
  EXPECT_EQ(sync.rtt_percentile_ns(0.0), 4 * ms);
  EXPECT_EQ(sync.rtt_percentile_ns(1.0), 20 * ms);
}

TEST(BrokerUrl, ParsesAndNamesTheFlag) {
  MqttOptions o;
  parse_broker_url("mqtt://127.0.0.1:18830", "--broker", o);
  EXPECT_EQ(o.host, "127.0.0.1");
  EXPECT_EQ(o.port, 18830);
  parse_broker_url("localhost", "--broker", o);
  EXPECT_EQ(o.host, "localhost");
  try {
    parse_broker_url("mqtt://host:99999", "--broker", o);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--broker"), std::string::npos);
  }
}

}  // namespace
}  // namespace kestrel::comm
