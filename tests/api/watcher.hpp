// A test's own MQTT client: a watching screen or an operator on the broker (Paho C++).
#pragma once

#include <mqtt/async_client.h>
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/api/broker.hpp"

namespace ncd::test {

// A subscriber (or a publisher) on the broker, as a watching screen or an operator would be.
// `persistent`: a session the broker keeps while the client is away (clean session off).
class Watcher {
 public:
  Watcher(const std::string& url, const std::string& id, const BrokerUser& user,
          const std::vector<std::string>& topics, bool persistent = false)
      : client_(url, id, static_cast<mqtt::iclient_persistence*>(nullptr)) {
    client_.start_consuming();
    auto opts =
        mqtt::connect_options_builder()
            .clean_session(!persistent)
            .user_name(user.name)
            .password(user.password)
            .automatic_reconnect(std::chrono::milliseconds(100), std::chrono::milliseconds(400))
            .finalize();
    client_.connect(opts)->wait_for(std::chrono::seconds(10));
    for (const auto& t : topics) client_.subscribe(t, 1)->wait_for(std::chrono::seconds(10));
  }
  ~Watcher() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (const std::exception&) {
    }
  }
  // The next message, or nullptr after timeout_s.
  mqtt::const_message_ptr next(double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      mqtt::const_message_ptr m;
      if (client_.try_consume_message_for(&m, std::chrono::milliseconds(50)) && m) return m;
    }
    return nullptr;
  }
  void publish(const std::string& topic, const nlohmann::json& payload) {
    client_.publish(topic, payload.dump(), 1, false)->wait_for(std::chrono::seconds(10));
  }
  mqtt::async_client& client() { return client_; }

 private:
  mqtt::async_client client_;
};

}  // namespace ncd::test
