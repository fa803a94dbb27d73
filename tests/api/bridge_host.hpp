// The MQTT bridge on its own io_context thread, as `ncd serve` runs it, with a status and a
// command handler of the test: the status counts its calls and says "running" from the
// state_switch-th call on; the command handler counts the commands and echoes their name.
#pragma once

#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>

#include "api/mqtt_bridge.hpp"

namespace ncd::test {

class BridgeHost {
 public:
  explicit BridgeHost(const api::MqttConfig& cfg, std::optional<std::string> token = {})
      : guard_(boost::asio::make_work_guard(io_)) {
    using nlohmann::json;
    bridge_ = std::make_unique<api::MqttBridge>(
        io_, cfg,
        [this] {
          const int n = ++status_calls;
          return json{{"ok", true},
                      {"state", n < state_switch ? "idle" : "running"},
                      {"position", {1.0, 2.0, 3.0}},
                      {"feed_mm_per_min", 600.0}};
        },
        [this](const json& request) {
          ++commands;
          return json{{"cmd", request["cmd"]}};
        },
        std::move(token));
    boost::asio::post(io_, [this] { bridge_->start(); });
    thread_ = std::thread([this] { io_.run(); });
  }
  ~BridgeHost() {
    boost::asio::post(io_, [this] { bridge_->stop(1.0); });
    guard_.reset();
    thread_.join();
    bridge_.reset();
  }
  BridgeHost(const BridgeHost&) = delete;
  BridgeHost& operator=(const BridgeHost&) = delete;

  api::MqttBridge& bridge() { return *bridge_; }
  // Whether the bridge's connection is `up` within timeout_s.
  bool wait_connected(bool up, double timeout_s = 20) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      if (bridge_->connected() == up) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  }

  std::atomic<int> status_calls{0}, commands{0};
  int state_switch = 1 << 30;  // the status call from which the state is "running"

 private:
  boost::asio::io_context io_;
  boost::asio::executor_work_guard<boost::asio::io_context::executor_type> guard_;
  std::unique_ptr<api::MqttBridge> bridge_;
  std::thread thread_;
};

}  // namespace ncd::test
