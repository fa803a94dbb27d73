// The [mqtt] table of the serve config: what it accepts, the defaults, and a clear refusal
// (naming the key, the value and the limit) for each kind of bad value; `ncd serve` exits 2 on
// one before it starts anything.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "api/mqtt_config.hpp"
#include "core/error.hpp"

namespace {

using ncd::InputError;
using ncd::api::MqttConfig;
using ncd::api::parse_mqtt_config;

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

// A folder with the three TLS files of a machine (their content is not read at config time).
class TlsFiles {
 public:
  TlsFiles()
      : dir_(std::filesystem::temp_directory_path() /
             ("ncd_fleet_tlsfiles_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(dir_);
    for (const char* name : {"ca.pem", "m1.pem", "m1.key"}) std::ofstream(dir_ / name) << "PEM\n";
  }
  ~TlsFiles() { std::filesystem::remove_all(dir_); }
  std::string operator()(const char* name) const { return (dir_ / name).string(); }

 private:
  std::filesystem::path dir_;
};

// No topic_root: "ncd/<host name>/", the host name read here with gethostname(2) (and its
// client id the root with '-' for '/').
TEST(MqttConfig, TheTopicRootDefaultsToTheHostName) {
  std::array<char, 256> name{};
  ASSERT_EQ(::gethostname(name.data(), name.size() - 1), 0);
  std::string host = name.data();
  for (char& ch : host) {
    if (ch == '/' || ch == '+' || ch == '#') ch = '-';
  }
  const MqttConfig c = parse("broker = \"tcp://x:1883\"\n");
  EXPECT_EQ(c.topic_root, "ncd/" + host + "/");
  EXPECT_EQ(c.client_id, "ncd-" + host);
  EXPECT_EQ(parse(kMinimal).topic_root, "ncd/c1/m1/");  // a given root wins
}

TEST(MqttConfig, EveryKeyIsRead) {
  const TlsFiles f;
  const MqttConfig c = parse(
      "broker = \"ssl://broker.shop:8883\"\ntopic_root = \"ncd/c1/m1/\"\nclient_id = \"lathe-7\"\n"
      "username = \"m1\"\npassword = \"pw\"\nca_file = \"" +
      f("ca.pem") + "\"\ncert_file = \"" + f("m1.pem") + "\"\nkey_file = \"" + f("m1.key") +
      "\"\nstatus_hz = 50\nqueue_bound = 20\nreconnect_min_s = 0.25\nreconnect_max_s = 10.0\n");
  EXPECT_TRUE(c.tls());
  EXPECT_EQ(c.client_id, "lathe-7");
  EXPECT_EQ(*c.username, "m1");
  EXPECT_EQ(*c.password, "pw");
  EXPECT_EQ(*c.ca_file, f("ca.pem"));
  EXPECT_EQ(*c.cert_file, f("m1.pem"));
  EXPECT_EQ(*c.key_file, f("m1.key"));
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

TEST(MqttConfig, TlsFilesThatCannotBeReadAreRefusedNamingTheKey) {
  const TlsFiles f;
  const std::string tls = "broker = \"ssl://x:8883\"\ntopic_root = \"a/\"\n";
  const std::string pair =
      "cert_file = \"" + f("m1.pem") + "\"\nkey_file = \"" + f("m1.key") + "\"\n";
  EXPECT_EQ(refusal(tls + pair + "ca_file = \"" + f("ca.pem") + "\"\n"), "");
  struct Case {
    std::string body;
    std::vector<std::string> says;
  };
  const std::string missing = f("nothing.pem");
  const std::vector<Case> cases = {
      {tls + "ca_file = \"" + missing + "\"\n",
       {"serve.toml: mqtt.ca_file = \"" + missing + "\"", "No such file", "PEM file"}},
      {tls + "cert_file = \"" + missing + "\"\nkey_file = \"" + f("m1.key") + "\"\n",
       {"mqtt.cert_file = \"" + missing + "\"", "cannot be read", "No such file"}},
      {tls + "cert_file = \"" + f("m1.pem") + "\"\nkey_file = \"" + missing + "\"\n",
       {"mqtt.key_file = \"" + missing + "\"", "cannot be read"}},
      {tls + pair + "ca_file = \"" + std::filesystem::temp_directory_path().string() + "\"\n",
       {"mqtt.ca_file", "a directory"}},
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

// page_url (the machine's page, in the online message for the cell page): http(s) only, no
// spaces, quotes or <>, bounded; without it `ncd serve` publishes its [http] address, a wildcard
// host replaced by the host name (a browser elsewhere cannot open 0.0.0.0).
TEST(MqttConfig, ThePageUrlIsALinkOrRefusedAndAWildcardHostBecomesTheHostName) {
  EXPECT_EQ(parse(kMinimal).page_url, "");
  EXPECT_EQ(parse(kMinimal + "page_url = \"https://cell1-m1:8443/\"\n").page_url,
            "https://cell1-m1:8443/");
  for (const std::string& bad : std::vector<std::string>{
           "javascript:alert(1)", "http://a b/", "ftp://m1/", "http://m1/\\\"><script>",
           std::string("http://") + std::string(2100, 'a')}) {
    const std::string why = refusal(kMinimal + "page_url = \"" + bad + "\"\n");
    EXPECT_NE(why.find("serve.toml: mqtt.page_url = "), std::string::npos) << bad << ": " << why;
    EXPECT_NE(why.find("http:// or https://, at most 2048 characters"), std::string::npos) << why;
  }
  std::array<char, 256> host{};
  ASSERT_EQ(::gethostname(host.data(), host.size() - 1), 0);
  const std::string name = host.data();
  EXPECT_EQ(ncd::api::reachable_page_url("http://0.0.0.0:8080/"), "http://" + name + ":8080/");
  EXPECT_EQ(ncd::api::reachable_page_url("https://[::]:8443/"), "https://" + name + ":8443/");
  EXPECT_EQ(ncd::api::reachable_page_url("http://127.0.0.1:8080/"), "http://127.0.0.1:8080/");
}

}  // namespace
