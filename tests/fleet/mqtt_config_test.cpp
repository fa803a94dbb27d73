// The [mqtt] table of the serve config: what it accepts, the defaults, and a clear refusal
// (naming the key, the value and the limit) for each kind of bad value; `ncd serve` exits 2 on
// one before it starts anything.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "fleet/mqtt_config.hpp"

namespace {

using ncd::InputError;
using ncd::fleet::MqttConfig;
using ncd::fleet::parse_mqtt_config;

MqttConfig parse(const std::string& body) {
  std::istringstream in("[mqtt]\n" + body);
  const toml::value root = toml::parse(in, "serve.toml");
  return parse_mqtt_config(toml::find(root, "mqtt"), "serve.toml: mqtt");
}

// The message of the InputError that parsing `body` throws ("" when it does not throw).
std::string refusal(const std::string& body) {
  try {
    parse(body);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

const std::string kMinimal = "broker = \"tcp://127.0.0.1:1883\"\ntopic_root = \"ncd/c1/m1/\"\n";

TEST(MqttConfig, TheMinimalTableTakesTheDefaults) {
  const MqttConfig c = parse(kMinimal);
  EXPECT_EQ(c.broker, "tcp://127.0.0.1:1883");
  EXPECT_EQ(c.topic_root, "ncd/c1/m1/");
  EXPECT_EQ(c.client_id, "ncd-c1-m1");  // the topic root, '/' as '-'
  EXPECT_EQ(c.status_hz, 10.0);
  EXPECT_EQ(c.queue_bound, 1000u);
  EXPECT_FALSE(c.username);
  EXPECT_FALSE(c.tls());
}

TEST(MqttConfig, EveryKeyIsRead) {
  const MqttConfig c = parse(
      "broker = \"ssl://broker.shop:8883\"\ntopic_root = \"ncd/c1/m1/\"\nclient_id = \"lathe-7\"\n"
      "username = \"m1\"\npassword = \"pw\"\nca_file = \"/etc/ncd/ca.pem\"\n"
      "cert_file = \"/etc/ncd/m1.pem\"\nkey_file = \"/etc/ncd/m1.key\"\nstatus_hz = 50\n"
      "queue_bound = 20\nreconnect_min_s = 0.25\nreconnect_max_s = 10.0\n");
  EXPECT_TRUE(c.tls());
  EXPECT_EQ(c.client_id, "lathe-7");
  EXPECT_EQ(*c.username, "m1");
  EXPECT_EQ(*c.password, "pw");
  EXPECT_EQ(*c.ca_file, "/etc/ncd/ca.pem");
  EXPECT_EQ(*c.key_file, "/etc/ncd/m1.key");
  EXPECT_EQ(c.status_hz, 50.0);
  EXPECT_EQ(c.queue_bound, 20u);
  EXPECT_EQ(c.reconnect_min_s, 0.25);
  EXPECT_EQ(c.reconnect_max_s, 10.0);
}

TEST(MqttConfig, BadValuesAreRefusedWithTheKeyTheValueAndTheLimit) {
  struct Case {
    std::string body;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases = {
      {"topic_root = \"ncd/c1/m1/\"\n", {"no broker", "tcp://HOST:1883"}},
      {"broker = \"http://x:1883\"\ntopic_root = \"a/\"\n", {"http://x:1883", "tcp://"}},
      {"broker = \"tcp://x:1883\"\n", {"no topic_root"}},
      {"broker = \"tcp://x:1883\"\ntopic_root = \"ncd/c1/m1\"\n",
       {"must end with '/'", "ncd/c1/m1/"}},
      {"broker = \"tcp://x:1883\"\ntopic_root = \"ncd/+/m1/\"\n", {"wildcard"}},
      {"broker = \"tcp://x:1883\"\ntopic_root = \"ncd//m1/\"\n", {"empty topic level"}},
      {"broker = \"tcp://x:1883\"\ntopic_root = \"/ncd/\"\n", {"empty topic level"}},
      {kMinimal + "status_hz = 0\n", {"status_hz = 0", "[0.1, 100]", "Hz"}},
      {kMinimal + "status_hz = 1000.0\n", {"status_hz = 1000", "[0.1, 100]"}},
      {kMinimal + "status_hz = nan\n", {"status_hz = nan"}},
      {kMinimal + "status_hz = \"fast\"\n", {"status_hz must be a number"}},
      {kMinimal + "queue_bound = 0\n", {"queue_bound = 0", "[1, 100000]"}},
      {kMinimal + "queue_bound = 2.5\n", {"queue_bound = 2.5", "whole number"}},
      {kMinimal + "queue_bound = 100001\n", {"queue_bound = 100001", "[1, 100000]"}},
      {kMinimal + "username = \"m1\"\n", {"username without a password", "both"}},
      {kMinimal + "password = \"pw\"\n", {"password without a username"}},
      {kMinimal + "ca_file = \"/ca.pem\"\n", {"TLS files", "plain TCP", "ssl://"}},
      {"broker = \"ssl://x:8883\"\ntopic_root = \"a/\"\ncert_file = \"/c.pem\"\n",
       {"cert_file without a key_file"}},
      {kMinimal + "reconnect_min_s = 5\nreconnect_max_s = 1\n",
       {"reconnect_max_s = 1", "below reconnect_min_s = 5"}},
      {kMinimal + "reconnect_min_s = 0\n", {"reconnect_min_s = 0", "[0.05, 3600]"}},
      {kMinimal + "client_id = \"\"\n", {"client_id is empty"}},
      {kMinimal + "brokr = \"tcp://x\"\n", {"unknown key", "brokr", "broker, client_id"}},
      {kMinimal + "username = 7\n", {"username must be a string", "7"}},
  };
  for (const Case& c : cases) {
    const std::string why = refusal(c.body);
    ASSERT_FALSE(why.empty()) << "accepted:\n" << c.body;
    for (const std::string& s : c.says) EXPECT_NE(why.find(s), std::string::npos) << why;
  }
}

TEST(MqttConfig, ServeRefusesABadTableWithExitTwo) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("ncd_fleet_cfg_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto config = dir / "serve.toml";
  std::ofstream(config) << "clock = \"simulated\"\nrealtime = false\n[mqtt]\n"
                        << kMinimal << "status_hz = 500\n";
  const std::string err = (dir / "err").string();
  const int raw = std::system((std::string(NCD_EXE) + " serve --config " + config.string() +
                               " --listen unix:" + (dir / "s.sock").string() + " 2>" + err)
                                  .c_str());
  std::ifstream in(err);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(WIFEXITED(raw));
  EXPECT_EQ(WEXITSTATUS(raw), 2);
  EXPECT_NE(text.find("status_hz = 500"), std::string::npos) << text;
  EXPECT_NE(text.find("[0.1, 100]"), std::string::npos) << text;
}

}  // namespace
