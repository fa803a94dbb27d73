// The serve config's one parser (api/service_config.cpp): the service's own keys, the
// dashboard's [http] and the fleet's [mqtt] read from one parse of the file, and a bad value in
// any of them refused with the file, the key as table.key, the value, the limit or the accepted
// values, and a way out.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "api/service_config.hpp"
#include "core/error.hpp"

namespace {

using ncd::InputError;
using ncd::api::parse_service_config;
using ncd::api::ServiceConfig;

std::string refusal(const std::string& text) {
  try {
    (void)parse_service_config(text, "serve.toml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

const std::string kMqtt =
    "[mqtt]\nbroker = \"tcp://127.0.0.1:1883\"\ntopic_root = \"ncd/c1/m1/\"\n";

TEST(ServeConfig, OneParseReadsTheServiceHttpAndMqttTables) {
  const ServiceConfig c = parse_service_config(
      "listen = \"tcp:127.0.0.1:7000\"\nclock = \"simulated\"\nrealtime = false\n"
      "[live_limits]\nfeed = \"report\"\n"
      "[http]\nlisten = \"tcp:127.0.0.1:8080\"\nstatus_hz = 25\n" +
          kMqtt + "status_hz = 50\n",
      "serve.toml");
  EXPECT_EQ(c.listen, "tcp:127.0.0.1:7000");
  EXPECT_EQ(c.clock, ncd::motion::ClockKind::Simulated);
  EXPECT_FALSE(c.realtime);
  EXPECT_EQ(c.live_limits.feed, ncd::service::RuleAction::Report);
  EXPECT_EQ(c.live_limits.accel, ncd::service::RuleAction::Error);
  ASSERT_TRUE(c.http.listen);
  EXPECT_EQ(*c.http.listen, "tcp:127.0.0.1:8080");
  EXPECT_EQ(c.http.status_hz, 25.0);
  ASSERT_TRUE(c.mqtt);
  EXPECT_EQ(c.mqtt->broker, "tcp://127.0.0.1:1883");
  EXPECT_EQ(c.mqtt->status_hz, 50.0);
  EXPECT_EQ(c.mqtt->client_id, "ncd-c1-m1");  // the topic root's default

  const ServiceConfig none = parse_service_config("realtime = true\n", "serve.toml");
  EXPECT_FALSE(none.http.listen);  // no [http]: no web server
  EXPECT_FALSE(none.mqtt);         // no [mqtt]: no bridge
  EXPECT_EQ(none.http.status_hz, 10.0);
}

TEST(ServeConfig, BadValuesAreRefusedNamingTheKeyTheValueTheLimitAndAWayOut) {
  struct Case {
    std::string text;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases = {
      // the service's own keys
      {"clock = \"fast\"\n", {"serve.toml: clock", "\"fast\"", "\"wall\"", "remove the key"}},
      {"realtime = \"yes\"\n", {"serve.toml: realtime", "\"yes\"", "true", "without quotes"}},
      {"listen = 7\n", {"serve.toml: listen", "7", "tcp:HOST:PORT", "quote it"}},
      {"listen = \"udp:1\"\n", {"serve.toml: listen", "udp:1"}},
      {"token = \"\"\n", {"serve.toml: token", "non-empty", "remove the key"}},
      {"live_limits = 3\n", {"serve.toml: live_limits", "3", "must be a table"}},
      {"[live_limits]\nfeed = \"warn\"\n",
       {"serve.toml: live_limits.feed", "\"warn\"", "\"error\"", "\"report\""}},
      {"colour = 1\n", {"unknown key serve.toml: colour", "[http]", "[mqtt]"}},
      // [http]
      {"[http]\nlisten = \"tcp:127.0.0.1:8080\"\nstatus_hz = 60\n",
       {"serve.toml: http.status_hz", "60", "at most 50", "give one in that range"}},
      {"[http]\nlisten = \"tcp:127.0.0.1:8080\"\nstatus_hz = 0\n",
       {"serve.toml: http.status_hz", "at least 1"}},
      {"[http]\nlisten = \"unix:/tmp/x\"\n", {"serve.toml: http.listen", "TCP only"}},
      {"[http]\nlisten = \"tcp:nowhere\"\n", {"serve.toml: http.listen", "tcp:nowhere"}},
      {"[http]\nlisten = 8080\n", {"serve.toml: http.listen", "8080", "quote it"}},
      {"[http]\nlisten = \"tcp:127.0.0.1:8080\"\ncertificate = \"c.pem\"\n",
       {"serve.toml: http", "certificate and key", "needs both"}},
      {"[http]\nassets = \"web\"\n", {"serve.toml: http", "no listen", "add listen"}},
      {"[http]\nport = 1\n", {"unknown key serve.toml: http.port", "status_hz"}},
      {"http = \"on\"\n", {"serve.toml: http", "\"on\"", "must be a table"}},
      // [mqtt]
      {kMqtt + "status_hz = 500\n",
       {"serve.toml: mqtt.status_hz", "500", "[0.1, 100] Hz", "give a value in that range"}},
      {kMqtt + "queue_bound = 0\n", {"serve.toml: mqtt.queue_bound", "[1, 100000]"}},
      {kMqtt + "reconnect_min_s = -1\n", {"serve.toml: mqtt.reconnect_min_s", "-1"}},
      {"[mqtt]\ntopic_root = \"ncd/c1/m1/\"\n", {"serve.toml: mqtt", "no broker", "add broker"}},
      {kMqtt + "username = \"m1\"\n", {"serve.toml: mqtt", "without a password", "give both"}},
      {kMqtt + "colour = 1\n", {"unknown key serve.toml: mqtt.colour", "topic_root"}},
      {"mqtt = 3\n", {"serve.toml: mqtt", "must be a table"}},
  };
  for (const Case& c : cases) {
    const std::string why = refusal(c.text);
    ASSERT_FALSE(why.empty()) << "accepted:\n" << c.text;
    for (const std::string& s : c.says) {
      EXPECT_NE(why.find(s), std::string::npos) << "'" << s << "' not in: " << why;
    }
  }
}

}  // namespace
