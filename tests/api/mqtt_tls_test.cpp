// The MQTT bridge against a real mosquitto that speaks only TLS (docs/fleet-mqtt.md, [mqtt]
// broker = "ssl://…", ca_file). The test makes its own certificate authority with openssl, and a
// server certificate for 127.0.0.1 signed by it, plus a second authority that signed nothing the
// broker shows. With the right CA the bridge connects and a TLS subscriber of the test receives
// its status; with the other CA, or in plain TCP on the TLS port, it never connects: the server's
// certificate is really checked.
//
// Client certificates (FleetTlsClientCert): the broker also says `require_certificate true`, and
// the test's CA signs a client certificate m1.pem; the other CA signs rogue.pem. With m1's
// certificate and key the bridge connects and publishes; without a certificate, or with rogue's,
// the broker refuses the handshake, and the bridge says why (last_failure(), the log), keeps
// its events queued and keeps trying with backoff.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "api/mqtt_bridge.hpp"
#include "tests/api/bridge_host.hpp"
#include "tests/api/broker.hpp"
#include "tests/common/process.hpp"

namespace {

using namespace std::chrono_literals;
using ncd::api::MqttBridge;
using ncd::api::MqttConfig;
using nlohmann::json;
namespace fs = std::filesystem;

const std::string kTlsRoot = "ncd/cell1/tls/";

using TlsHost = ncd::test::BridgeHost;

class FleetTls : public ::testing::Test {
 protected:
  bool require_certificate_ = false;  // the broker asks every client for a certificate

  void SetUp() override {
    if (const std::string why = ncd::test::Broker::missing(); !why.empty()) GTEST_SKIP() << why;
    if (ncd::test::find_program("openssl").empty()) {
      GTEST_SKIP() << "openssl is not installed; the TLS test makes its certificates with it";
    }
    dir_ = fs::temp_directory_path() /
           ("ncd_fleet_tls_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    make_certificates();
    port_ = ncd::test::free_loopback_port();
    std::ofstream conf(dir_ / "mosquitto.conf");
    conf << "listener " << port_ << " 127.0.0.1\n"
         << "cafile " << (dir_ / "ca.pem").string() << "\n"
         << "certfile " << (dir_ / "server.pem").string() << "\n"
         << "keyfile " << (dir_ / "server.key").string() << "\n"
         << "allow_anonymous true\n"
         << "require_certificate " << (require_certificate_ ? "true" : "false") << "\n"
         << "log_dest stderr\n";
    if (::geteuid() == 0) conf << "user root\n";  // keep access to the key in the test folder
    conf.close();
    broker_ = std::make_unique<ncd::test::Process>(
        std::vector<std::string>{ncd::test::find_program("mosquitto"), "-c",
                                 (dir_ / "mosquitto.conf").string()},
        (dir_ / "mosquitto.out").string(), (dir_ / "mosquitto.err").string());
    const auto end = std::chrono::steady_clock::now() + 10s;
    while (!ncd::test::port_accepts(port_) && std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(20ms);
    }
    ASSERT_TRUE(ncd::test::port_accepts(port_)) << log();
  }
  void TearDown() override {
    if (broker_) {
      broker_->signal(SIGTERM);
      broker_->wait(10);
      broker_.reset();
    }
    if (!dir_.empty()) fs::remove_all(dir_);
  }

  void openssl(const std::string& args) {
    const std::string cmd = "cd " + dir_.string() + " && openssl " + args + " >>openssl.log 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  }
  // ca.pem signs server.pem (CN and subjectAltName 127.0.0.1); other-ca.pem signs nothing here.
  void make_certificates() {
    openssl(
        "req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem -days 2 "
        "-subj /CN=ncd-test-ca");
    openssl(
        "req -x509 -newkey rsa:2048 -nodes -keyout other-ca.key -out other-ca.pem -days 2 "
        "-subj /CN=ncd-other-ca");
    openssl(
        "req -newkey rsa:2048 -nodes -keyout server.key -out server.csr "
        "-subj /CN=127.0.0.1");
    std::ofstream(dir_ / "san.ext") << "subjectAltName = IP:127.0.0.1\n";
    openssl(
        "x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem "
        "-days 2 -extfile san.ext");
    if (!require_certificate_) return;
    // The machine's client certificate (ca.pem signs it) and a rogue one (other-ca.pem does).
    for (const auto& [name, ca] :
         {std::pair<std::string, std::string>{"m1", "ca"}, {"rogue", "other-ca"}}) {
      openssl("req -newkey rsa:2048 -nodes -keyout " + name + ".key -out " + name +
              ".csr -subj /CN=" + name);
      openssl("x509 -req -in " + name + ".csr -CA " + ca + ".pem -CAkey " + ca +
              ".key -CAcreateserial -out " + name + ".pem -days 2");
    }
  }
  std::string log() const {
    std::ifstream in(dir_ / "mosquitto.err");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  MqttConfig config(const std::string& scheme, const std::string& ca) const {
    MqttConfig c;
    c.broker = scheme + "://127.0.0.1:" + std::to_string(port_);
    c.client_id = "ncd-cell1-tls";
    c.topic_root = kTlsRoot;
    c.status_hz = 20.0;
    c.reconnect_min_s = 0.1;
    c.reconnect_max_s = 0.4;
    if (!ca.empty()) c.ca_file = (dir_ / ca).string();
    return c;
  }

  fs::path dir_;
  int port_ = 0;
  std::unique_ptr<ncd::test::Process> broker_;
};

TEST_F(FleetTls, WithTheBrokersCaTheBridgeConnectsAndItsStatusArrives) {
  TlsHost host(config("ssl", "ca.pem"));
  ASSERT_TRUE(host.wait_connected(true, 20.0)) << log();
  // A subscriber of the test over TLS, checking the broker's certificate against the same CA.
  mqtt::async_client watcher("ssl://127.0.0.1:" + std::to_string(port_), "watch-tls",
                             static_cast<mqtt::iclient_persistence*>(nullptr));
  watcher.start_consuming();
  auto ssl = mqtt::ssl_options_builder()
                 .enable_server_cert_auth(true)
                 .trust_store((dir_ / "ca.pem").string())
                 .finalize();
  auto opts = mqtt::connect_options_builder().clean_session(true).ssl(ssl).finalize();
  ASSERT_TRUE(watcher.connect(opts)->wait_for(10s)) << log();
  ASSERT_TRUE(watcher.subscribe(kTlsRoot + "status", 0)->wait_for(10s));
  int status = 0;
  const auto end = std::chrono::steady_clock::now() + 20s;
  while (status < 3 && std::chrono::steady_clock::now() < end) {
    mqtt::const_message_ptr m;
    if (watcher.try_consume_message_for(&m, 100ms) && m && m->get_topic() == kTlsRoot + "status") {
      EXPECT_EQ(json::parse(m->to_string())["state"], "idle");
      ++status;
    }
  }
  EXPECT_EQ(status, 3) << log();
  EXPECT_GE(host.bridge().counters().status_published, 3u);
  watcher.disconnect()->wait_for(2s);
}

TEST_F(FleetTls, WithAnotherCaOrPlainTcpTheBridgeNeverConnects) {
  {
    TlsHost host(config("ssl", "other-ca.pem"));  // the broker's certificate is not trusted
    EXPECT_FALSE(host.wait_connected(true, 3.0));
    EXPECT_EQ(host.bridge().counters().connects, 0u);
  }
  {
    TlsHost host(config("tcp", ""));  // plain MQTT on the TLS port
    EXPECT_FALSE(host.wait_connected(true, 3.0));
    EXPECT_EQ(host.bridge().counters().connects, 0u);
  }
  // The broker is still there for the right client: the refusals were the certificate's.
  TlsHost good(config("ssl", "ca.pem"));
  EXPECT_TRUE(good.wait_connected(true, 20.0)) << log();
}

class FleetTlsClientCert : public FleetTls {
 protected:
  FleetTlsClientCert() { require_certificate_ = true; }
  MqttConfig with_cert(const std::string& name) const {
    MqttConfig c = config("ssl", "ca.pem");
    c.cert_file = (dir_ / (name + ".pem")).string();
    c.key_file = (dir_ / (name + ".key")).string();
    return c;
  }
};

TEST_F(FleetTlsClientCert, WithACertificateOfTheBrokersCaTheBridgeConnectsAndPublishes) {
  TlsHost host(with_cert("m1"));
  ASSERT_TRUE(host.wait_connected(true, 20.0)) << log();
  // A subscriber of the test, with the same client certificate (the broker asks everyone).
  mqtt::async_client watcher("ssl://127.0.0.1:" + std::to_string(port_), "watch-cert",
                             static_cast<mqtt::iclient_persistence*>(nullptr));
  watcher.start_consuming();
  auto ssl = mqtt::ssl_options_builder()
                 .enable_server_cert_auth(true)
                 .trust_store((dir_ / "ca.pem").string())
                 .key_store((dir_ / "m1.pem").string())
                 .private_key((dir_ / "m1.key").string())
                 .finalize();
  auto opts = mqtt::connect_options_builder().clean_session(true).ssl(ssl).finalize();
  ASSERT_TRUE(watcher.connect(opts)->wait_for(10s)) << log();
  ASSERT_TRUE(watcher.subscribe(kTlsRoot + "#", 1)->wait_for(10s));
  ASSERT_TRUE(host.bridge().push_event(json{{"kind", "job"}, {"text", "started"}}));
  int status = 0;
  bool event = false;
  const auto end = std::chrono::steady_clock::now() + 20s;
  while ((status < 3 || !event) && std::chrono::steady_clock::now() < end) {
    mqtt::const_message_ptr m;
    if (!watcher.try_consume_message_for(&m, 100ms) || !m) continue;
    if (m->get_topic() == kTlsRoot + "status") {
      EXPECT_EQ(json::parse(m->to_string())["state"], "idle");
      ++status;
    } else if (m->get_topic() == kTlsRoot + "events") {
      EXPECT_EQ(json::parse(m->to_string())["text"], "started");
      event = true;
    }
  }
  EXPECT_EQ(status, 3) << log();
  EXPECT_TRUE(event) << log();
  EXPECT_EQ(host.bridge().counters().connect_failures, 0u);
  EXPECT_EQ(host.bridge().last_failure(), "");
  watcher.disconnect()->wait_for(2s);
}

TEST_F(FleetTlsClientCert, WithoutACertificateOrWithAnotherCasTheBrokerRefusesAndTheBridgeGoesOn) {
  for (const std::string name : {"", "rogue"}) {
    SCOPED_TRACE(name.empty() ? "no client certificate" : "a certificate of another CA");
    TlsHost host(name.empty() ? config("ssl", "ca.pem") : with_cert(name));
    // Refused, and tried again with backoff (0.1 s doubled up to 0.4 s): at least two failed
    // attempts, none connected.
    const auto end = std::chrono::steady_clock::now() + 30s;
    while (host.bridge().counters().connect_failures < 2 &&
           std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(20ms);
    }
    const auto n = host.bridge().counters();
    EXPECT_GE(n.connect_failures, 2u) << log();
    EXPECT_EQ(n.connects, 0u);
    EXPECT_FALSE(host.bridge().connected());
    // It says why, in the words of the log line.
    EXPECT_NE(host.bridge().last_failure().find("TLS handshake failed"), std::string::npos)
        << host.bridge().last_failure();
    // The bridge keeps running: events are queued for later, none dropped.
    for (int k = 0; k < 5; ++k) EXPECT_TRUE(host.bridge().push_event(json{{"k", k}}));
    EXPECT_EQ(host.bridge().counters().events_pushed, 5u);
    EXPECT_EQ(host.bridge().counters().events_dropped, 0u);
    EXPECT_FALSE(host.bridge().connected());
  }
  // The broker said why (OpenSSL's words in its log), and it still takes the right client.
  EXPECT_NE(log().find("certificate"), std::string::npos) << log();
  TlsHost good(with_cert("m1"));
  EXPECT_TRUE(good.wait_connected(true, 20.0)) << log();
}

}  // namespace
