// The MQTT bridge against a real mosquitto (tests/api/broker.hpp): status at the set rate,
// the state on change, events in order, no event lost across a broker killed and restarted
// (within the bound, and the overflow counted exactly), the broker's password file and ACL,
// and commands through the control socket's checks. Skipped when mosquitto is not installed.
#include <gtest/gtest.h>

#include <mqtt/async_client.h>
#include <algorithm>
#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <chrono>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "api/mqtt_bridge.hpp"
#include "tests/api/bridge_host.hpp"
#include "tests/api/broker.hpp"
#include "tests/api/watcher.hpp"

namespace {

using namespace std::chrono_literals;
using ncd::api::MqttBridge;
using ncd::api::MqttConfig;
using ncd::test::Broker;
using ncd::test::BrokerUser;
using ncd::test::Watcher;
using nlohmann::json;
namespace fs = std::filesystem;

const std::string kRoot = "ncd/cell1/m1/";

using Host = ncd::test::BridgeHost;

class Fleet : public ::testing::Test {
 protected:
  void SetUp() override {
    if (const std::string why = Broker::missing(); !why.empty()) GTEST_SKIP() << why;
    dir_ = fs::temp_directory_path() /
           ("ncd_fleet_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    broker_ = std::make_unique<Broker>(dir_);
    ASSERT_TRUE(broker_->start()) << broker_->log();
  }
  void TearDown() override {
    broker_.reset();
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  MqttConfig config() const {
    MqttConfig c;
    c.broker = broker_->url();
    c.client_id = "ncd-cell1-m1";
    c.username = ncd::test::kMachine.name;
    c.password = ncd::test::kMachine.password;
    c.topic_root = kRoot;
    c.reconnect_min_s = 0.1;
    c.reconnect_max_s = 0.4;
    return c;
  }
  // Collects the distinct "seq" of events (the first of each, in arrival order) until `want`
  // distinct ones have come or timeout_s has passed; counts duplicates.
  static void collect(Watcher& w, std::vector<std::uint64_t>& seqs, std::set<std::uint64_t>& seen,
                      std::size_t want, int& duplicates, double timeout_s = 20) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (seen.size() < want && std::chrono::steady_clock::now() < end) {
      auto m = w.next(0.2);
      if (!m || m->get_topic() != kRoot + "events") continue;
      const auto seq = json::parse(m->to_string())["seq"].get<std::uint64_t>();
      if (seen.insert(seq).second) {
        seqs.push_back(seq);
      } else {
        ++duplicates;
      }
    }
  }

  fs::path dir_;
  std::unique_ptr<Broker> broker_;
};

TEST_F(Fleet, StatusArrivesAtTheSetRateAndTheStateOnChange) {
  constexpr double kHz = 20.0;
  Watcher w(broker_->url(), "watch-rate", ncd::test::kOperator,
            {kRoot + "status", kRoot + "state"});
  MqttConfig cfg = config();
  cfg.status_hz = kHz;
  Host host(cfg);
  host.state_switch = 25;  // "running" from the 25th status on
  std::vector<double> t_s;
  std::vector<std::string> states;
  json last;
  // Two seconds of status by the bridge's clock (or 20 s of waiting on a loaded machine).
  const auto end = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < end && (t_s.size() < 2 || t_s.back() - t_s[1] < 2.0)) {
    auto m = w.next(0.1);
    if (!m) continue;
    const json p = json::parse(m->to_string());
    if (m->get_topic() == kRoot + "state") {
      states.push_back(p["state"]);
    } else {
      t_s.push_back(p["time_s"].get<double>());
      last = p;
    }
  }
  ASSERT_GE(t_s.size(), 3u);
  // The first status is the one sent on connecting; the rest follow the timer's deadlines.
  const double span_s = t_s.back() - t_s[1];
  const double intervals = static_cast<double>(t_s.size() - 2);
  std::printf("first status at %.3f s after start\n", t_s[0]);
  std::printf("status: %zu messages over %.3f s (bridge's clock) = %.2f Hz, set %.1f Hz\n",
              t_s.size() - 1, span_s, intervals / span_s, kHz);
  // Absolute deadlines one period apart, a late tick never caught up: at most span/period + 2
  // ticks in any span (exact); the lower bound is loose, for a loaded machine.
  EXPECT_LE(intervals, kHz * span_s + 2.0);
  EXPECT_GE(intervals, 0.5 * kHz * span_s);
  EXPECT_GE(span_s, 1.5);
  // Units in the names: the position in mm, the socket's "ok" left out.
  EXPECT_EQ(last["position_mm"], json({1.0, 2.0, 3.0}));
  EXPECT_FALSE(last.contains("position"));
  EXPECT_FALSE(last.contains("ok"));
  EXPECT_EQ(last["events_dropped"], 0);
  // The state on change only: idle, then running once.
  EXPECT_EQ(states, (std::vector<std::string>{"idle", "running"}));
}

TEST_F(Fleet, EventsArriveInOrder) {
  Watcher w(broker_->url(), "watch-order", ncd::test::kOperator, {kRoot + "events"});
  Host host(config());
  ASSERT_TRUE(host.wait_connected(true));
  constexpr int kEvents = 500;
  for (int i = 1; i <= kEvents; ++i) {
    ASSERT_TRUE(host.bridge().push_event({{"type", "line"}, {"line", i}}));
  }
  std::vector<std::uint64_t> seqs;
  std::set<std::uint64_t> seen;
  int duplicates = 0;
  collect(w, seqs, seen, kEvents, duplicates);
  ASSERT_EQ(seqs.size(), static_cast<std::size_t>(kEvents));
  for (int i = 0; i < kEvents; ++i) ASSERT_EQ(seqs[static_cast<std::size_t>(i)], i + 1u);
  EXPECT_EQ(duplicates, 0);  // no reconnection, no second sending
  const auto n = host.bridge().counters();
  EXPECT_EQ(n.events_pushed, static_cast<std::uint64_t>(kEvents));
  EXPECT_EQ(n.events_dropped, 0u);
}

// Waits until the broker has acknowledged `n` events (the queue has room again).
bool wait_published(MqttBridge& b, std::uint64_t n) {
  for (int i = 0; i < 3000; ++i) {
    if (b.counters().events_published >= n) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

// Pushes `count` events numbered from `from` (the event's own "i" is the expected seq).
void push(MqttBridge& b, int from, int count, int& accepted) {
  for (int i = from; i < from + count; ++i) accepted += b.push_event({{"type", "tick"}, {"i", i}});
}

TEST_F(Fleet, BrokerKilledAndRestartedMidJobLosesNoEventWithinTheBound) {
  // A persistent session: the broker keeps what comes for the watcher while it reconnects.
  Watcher w(broker_->url(), "watch-restart", ncd::test::kOperator, {kRoot + "events"}, true);
  std::this_thread::sleep_for(1500ms);  // the broker saves the subscription (autosave)
  MqttConfig cfg = config();
  cfg.queue_bound = 50;
  Host host(cfg);
  ASSERT_TRUE(host.wait_connected(true));
  int accepted = 0;
  push(host.bridge(), 1, 30, accepted);
  std::vector<std::uint64_t> seqs;
  std::set<std::uint64_t> seen;
  int duplicates = 0;
  collect(w, seqs, seen, 30, duplicates);
  ASSERT_EQ(seen.size(), 30u);
  push(host.bridge(), 31, 10, accepted);  // may be in flight when the broker dies
  broker_->kill();
  push(host.bridge(), 41, 10, accepted);  // some while the bridge still thinks it is connected
  ASSERT_TRUE(host.wait_connected(false));
  push(host.bridge(), 51, 20, accepted);  // with the broker away: 40 at most wait, bound 50
  std::this_thread::sleep_for(500ms);
  ASSERT_TRUE(broker_->start()) << broker_->log();
  ASSERT_TRUE(host.wait_connected(true));
  ASSERT_TRUE(wait_published(host.bridge(), 70));  // the 70 so far, before the next 30
  push(host.bridge(), 71, 30, accepted);
  collect(w, seqs, seen, 100, duplicates, 30);
  const auto n = host.bridge().counters();
  std::printf(
      "restart: %zu of 100 events arrived (%d duplicates), %llu dropped, %llu resent, "
      "%llu connections, %llu lost\n",
      seen.size(), duplicates, static_cast<unsigned long long>(n.events_dropped),
      static_cast<unsigned long long>(n.events_resent), static_cast<unsigned long long>(n.connects),
      static_cast<unsigned long long>(n.connection_losses));
  EXPECT_EQ(accepted, 100);
  EXPECT_EQ(n.events_dropped, 0u);
  ASSERT_EQ(seen.size(), 100u);
  EXPECT_EQ(*seen.begin(), 1u);
  EXPECT_EQ(*seen.rbegin(), 100u);
  // In order: the first arrival of each seq comes after every smaller one's, except inside the
  // window in flight around the broker's death (31-70). There QoS 1 redelivers what was not
  // acknowledged when the broker died, after later messages it had already passed on (seen once
  // under load: 32-40, then 31); a consumer orders by `seq`, which every event carries. Before
  // the kill and after the reconnect the order is strict.
  for (std::size_t i = 1; i < seqs.size(); ++i) {
    const bool in_flight_window = seqs[i] > 30 && seqs[i] <= 70;
    if (in_flight_window) continue;
    EXPECT_LT(*std::max_element(seqs.begin(), seqs.begin() + static_cast<std::ptrdiff_t>(i)),
              seqs[i])
        << "at " << i;
  }
  EXPECT_EQ(n.connects, 2u);
  EXPECT_GE(n.connection_losses, 1u);
}

TEST_F(Fleet, PastTheBoundEventsAreDroppedAndCountedNeverWaitedFor) {
  Watcher w(broker_->url(), "watch-bound", ncd::test::kOperator,
            {kRoot + "events", kRoot + "status"}, true);
  std::this_thread::sleep_for(1500ms);
  MqttConfig cfg = config();
  cfg.queue_bound = 20;
  Host host(cfg);
  ASSERT_TRUE(host.wait_connected(true));
  int accepted = 0;
  push(host.bridge(), 1, 10, accepted);
  std::vector<std::uint64_t> seqs;
  std::set<std::uint64_t> seen;
  int duplicates = 0;
  collect(w, seqs, seen, 10, duplicates);
  ASSERT_EQ(seen.size(), 10u);
  broker_->kill();
  ASSERT_TRUE(host.wait_connected(false));
  push(host.bridge(), 11, 50, accepted);  // 20 fit, 30 are dropped: the newest
  EXPECT_EQ(accepted, 30);
  EXPECT_EQ(host.bridge().counters().events_dropped, 30u);
  ASSERT_TRUE(broker_->start()) << broker_->log();
  ASSERT_TRUE(host.wait_connected(true));
  ASSERT_TRUE(wait_published(host.bridge(), 30));  // the 30 accepted, before the next 5
  push(host.bridge(), 61, 5, accepted);
  collect(w, seqs, seen, 35, duplicates, 30);
  std::set<std::uint64_t> expected;
  for (std::uint64_t s = 1; s <= 30; ++s) expected.insert(s);
  for (std::uint64_t s = 61; s <= 65; ++s) expected.insert(s);
  EXPECT_EQ(seen, expected);  // the gap 31..60 is the 30 dropped
  std::printf("bound 20: pushed 65, %llu dropped while the broker was away, %zu arrived\n",
              static_cast<unsigned long long>(host.bridge().counters().events_dropped),
              seen.size());
  // The status tells the count.
  json status;
  for (int i = 0; i < 100 && !status.contains("events_dropped"); ++i) {
    auto m = w.next(0.2);
    if (m && m->get_topic() == kRoot + "status") status = json::parse(m->to_string());
  }
  EXPECT_EQ(status["events_dropped"], 30);
}

TEST_F(Fleet, TheBrokerRefusesClientsWithoutCredentialsAndKeepsMachinesApart) {
  for (const auto& [user, password] : std::vector<std::pair<std::string, std::string>>{
           {"", ""}, {"m1", "wrong"}, {"nobody", "x"}}) {
    mqtt::async_client c(broker_->url(), "intruder",
                         static_cast<mqtt::iclient_persistence*>(nullptr));
    auto b = mqtt::connect_options_builder().clean_session(true);
    if (!user.empty()) b.user_name(user).password(password);
    // The broker answers CONNACK 5 (not authorised) or 4 (bad user name or password).
    int rc = 0;
    try {
      if (!c.connect(b.finalize())->wait_for(10s)) ADD_FAILURE() << "no CONNACK";
    } catch (const mqtt::exception& e) {
      rc = e.get_return_code();
      std::printf("user \"%s\": refused (%s)\n", user.c_str(), e.what());
    }
    const bool refused = rc == 4 || rc == 5;
    EXPECT_TRUE(refused) << "user \"" << user << "\" was let in";
  }
  // Machine m2 may not command m1 (its ACL covers ncd/cell1/m2/# only): the broker drops the
  // message. The operator may, and a command without the token gets the socket's refusal.
  Host host(config(), std::string("t0k"));
  ASSERT_TRUE(host.wait_connected(true));
  Watcher ops(broker_->url(), "ops-1", ncd::test::kOperator, {kRoot + "reply"});
  Watcher m2(broker_->url(), "ncd-cell1-m2", ncd::test::kOtherMachine, {});
  m2.publish(kRoot + "cmd", {{"cmd", "stop"}, {"token", "t0k"}, {"id", 1}});
  ops.publish(kRoot + "cmd", {{"cmd", "hold"}, {"id", 2}});
  ops.publish(kRoot + "cmd", {{"cmd", "hold"}, {"token", "t0k"}, {"id", 3}});
  std::map<int, json> replies;
  for (int i = 0; i < 50 && replies.size() < 2; ++i) {
    if (auto m = ops.next(0.2)) {
      const json r = json::parse(m->to_string());
      replies[r.value("id", 0)] = r;
    }
  }
  EXPECT_FALSE(replies.count(1)) << "m2's command reached m1";
  ASSERT_TRUE(replies.count(2));
  EXPECT_FALSE(replies[2]["ok"].get<bool>());
  EXPECT_NE(replies[2].dump().find("token"), std::string::npos) << replies[2].dump();
  ASSERT_TRUE(replies.count(3));
  EXPECT_TRUE(replies[3]["ok"].get<bool>());
  EXPECT_EQ(replies[3]["cmd"], "hold");
  EXPECT_EQ(host.commands.load(), 1);  // only the operator's command with the token
}

}  // namespace
