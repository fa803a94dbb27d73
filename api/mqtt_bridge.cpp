// The MQTT bridge (docs/fleet-mqtt.md). How it works, once:
//
// - Connecting never blocks: Paho's asynchronous connect returns at once; success comes back
//   through the connected handler, failure through the connect listener. Each failure or lost
//   connection schedules the next attempt on a timer, after reconnect_min_s doubled per failed
//   attempt up to reconnect_max_s (exponential backoff); a success resets it.
// - Events: push_event() puts (seq, event) into a single-producer single-consumer ring of
//   queue_bound slots (two atomics, no lock, no wait). The pump timer (every 10 ms, on the
//   io_context) moves events from the ring to the in-flight list, at most queue_bound of them,
//   and publishes each at QoS 1. An event leaves the in-flight list when the broker
//   acknowledges it (and every older one has left). A lost connection marks every
//   unacknowledged event to be sent again, in order, after the reconnection: QoS 1 means "at
//   least once", so a subscriber may see an event twice and keeps the first of each "seq".
//   While the broker is away the pump moves nothing, the ring fills, and push_event() drops
//   what does not fit, counting it.
// - Status: a timer at status_hz on absolute deadlines (a late tick does not make the next
//   ones early; a tick more than one period late is skipped, never caught up in a burst) asks
//   the status callback for a snapshot and publishes it at QoS 0 (the next one replaces a lost
//   one). The snapshot's "state" is compared with the last one sent: a change is published,
//   retained at QoS 1, on the state topic.
// - Online: connected, the bridge publishes {"online": true} retained; the broker publishes the
//   last will {"online": false} retained when the connection dies without a DISCONNECT; stop()
//   publishes it itself before disconnecting.
// - Commands: each message on the command topic goes through comms::check_request() with the
//   control socket's options (the same JSON checks and the same token), then to the command
//   callback; the reply is published on the reply topic with the request's "id".
#include "api/mqtt_bridge.hpp"

#include <mqtt/async_client.h>
#include <algorithm>
#include <atomic>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <deque>
#include <iostream>
#include <mutex>
#include <vector>

#include "api/control_server.hpp"
#include "core/error.hpp"

namespace ncd::api {

using nlohmann::json;
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kPumpPeriod = std::chrono::milliseconds(10);

double unix_time_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

struct QueuedEvent {
  std::uint64_t seq = 0;
  json event;
};

// A bounded single-producer single-consumer ring: push on the producer's thread, pop on the
// consumer's. One slot stays empty to tell full from empty.
class EventRing {
 public:
  explicit EventRing(std::size_t bound) : slots_(bound + 1) {}
  bool push(QueuedEvent&& e) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t next = tail + 1 == slots_.size() ? 0 : tail + 1;
    if (next == head_.load(std::memory_order_acquire)) return false;
    slots_[tail] = std::move(e);
    tail_.store(next, std::memory_order_release);
    return true;
  }
  bool pop(QueuedEvent& out) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_.load(std::memory_order_acquire)) return false;
    out = std::move(slots_[head]);
    slots_[head] = QueuedEvent{};
    head_.store(head + 1 == slots_.size() ? 0 : head + 1, std::memory_order_release);
    return true;
  }
  std::size_t size() const {
    const std::size_t head = head_.load(std::memory_order_acquire);
    const std::size_t tail = tail_.load(std::memory_order_acquire);
    return tail >= head ? tail - head : tail + slots_.size() - head;
  }

 private:
  std::vector<QueuedEvent> slots_;
  std::atomic<std::size_t> head_{0}, tail_{0};
};

// An action listener made of two functions (Paho's threads call them).
class Listener : public mqtt::iaction_listener {
 public:
  std::function<void(const mqtt::token&)> success, failure;

 private:
  void on_success(const mqtt::token& tok) override {
    if (success) success(tok);
  }
  void on_failure(const mqtt::token& tok) override {
    if (failure) failure(tok);
  }
};

// The "id" of a refused request, to match the refusal to it: the top level only is kept while
// parsing (nested values are dropped as they are read), so no depth is built up.
json request_id(const std::string& payload) {
  const json top = json::parse(
      payload, [](int depth, json::parse_event_t, json&) { return depth <= 1; }, false);
  if (!top.is_object()) return json();
  const auto it = top.find("id");
  return it != top.end() && (it->is_string() || it->is_number()) ? *it : json();
}

// A failed connection attempt in words: Paho's return code, the broker's CONNACK refusals
// (MQTT 3.1.1, 3.2.2.3) and what -1 means. (Paho C++ 1.2's ssl_options error handler cannot be
// used for the TLS library's own words: the C library keeps a pointer to the options object that
// the connect options copy leaves behind.)
std::string connect_failure_text(int rc, bool tls) {
  std::string why = "code " + std::to_string(rc);
  switch (rc) {
    case -1:
      return why + (tls ? ": the TCP connection or the TLS handshake failed (no broker there, or "
                          "a certificate refused: check ca_file against the broker's certificate, "
                          "and cert_file, key_file against the broker's cafile)"
                        : ": the TCP connection failed (no broker there)");
    case 1:
      return why + ": the broker refused the protocol version";
    case 2:
      return why + ": the broker refused the client id";
    case 3:
      return why + ": the broker is unavailable";
    case 4:
      return why + ": bad user name or password";
    case 5:
      return why + ": not authorised (the broker's ACL or its password file)";
    default:
      return why;
  }
}

using comms::error_reply;

void* seq_context(std::uint64_t seq) {
  return reinterpret_cast<void*>(static_cast<std::uintptr_t>(seq));
}
std::uint64_t context_seq(const mqtt::token& tok) {
  return static_cast<std::uint64_t>(reinterpret_cast<std::uintptr_t>(tok.get_user_context()));
}

}  // namespace

struct MqttBridge::Core : std::enable_shared_from_this<MqttBridge::Core> {
  struct Pending {
    std::uint64_t seq = 0;
    std::string payload;
    bool sent = false;      // published on the current connection
    bool acked = false;     // the broker has it
    bool was_sent = false;  // published at least once (a second time counts as resent)
  };

  Core(boost::asio::io_context& io_context, const MqttConfig& config, StatusFn status,
       CommandFn command, std::optional<std::string> token)
      : io(io_context),
        cfg(config),
        status_fn(std::move(status)),
        command_fn(std::move(command)),
        status_timer(io_context),
        pump_timer(io_context),
        reconnect_timer(io_context),
        ring(config.queue_bound) {
    options.token = std::move(token);
    t_status = cfg.topic_root + "status";
    t_state = cfg.topic_root + "state";
    t_events = cfg.topic_root + "events";
    t_online = cfg.topic_root + "online";
    t_cmd = cfg.topic_root + "cmd";
    t_reply = cfg.topic_root + "reply";
    try {
      client = std::make_unique<mqtt::async_client>(
          cfg.broker, cfg.client_id, static_cast<mqtt::iclient_persistence*>(nullptr));
    } catch (const std::exception& e) {
      throw InputError("[mqtt] broker = \"" + cfg.broker + "\" is refused by the MQTT client (" +
                       e.what() + "); write it as tcp://HOST:PORT or ssl://HOST:PORT");
    }
    auto builder = mqtt::connect_options_builder()
                       .clean_session(true)
                       .keep_alive_interval(std::chrono::seconds(10))
                       .connect_timeout(std::chrono::seconds(5))
                       .automatic_reconnect(false)
                       .will(mqtt::will_options(t_online, offline_payload(), 1, true));
    if (cfg.username) builder.user_name(*cfg.username).password(*cfg.password);
    if (cfg.tls()) {
      auto ssl = mqtt::ssl_options_builder();
      ssl.enable_server_cert_auth(true);
      if (cfg.ca_file) ssl.trust_store(*cfg.ca_file);
      if (cfg.cert_file) ssl.key_store(*cfg.cert_file).private_key(*cfg.key_file);
      builder.ssl(ssl.finalize());
    }
    connect_opts = builder.finalize();
  }

  static std::string offline_payload() { return json{{"online", false}}.dump(); }

  // Runs f on the io_context if the core still exists (Paho's threads call this).
  template <class F>
  void on_io(F f) {
    boost::asio::post(io, [w = weak_from_this(), f = std::move(f)]() mutable {
      if (auto c = w.lock()) {
        if (!c->stopped) f(*c);
      }
    });
  }

  void start() {
    if (started) return;
    started = true;
    t0 = Clock::now();
    client->set_connected_handler(
        [this](const std::string&) { on_io([](Core& c) { c.on_connected(); }); });
    client->set_connection_lost_handler(
        [this](const std::string& cause) { on_io([cause](Core& c) { c.on_lost(cause); }); });
    client->set_message_callback([this](mqtt::const_message_ptr m) {
      on_io([payload = m->to_string()](Core& c) { c.on_command(payload); });
    });
    connect_listener.failure = [this](const mqtt::token& tok) {
      const int rc = tok.get_return_code();
      on_io([rc](Core& c) { c.on_connect_failed(rc); });
    };
    publish_listener.success = [this](const mqtt::token& tok) {
      const std::uint64_t seq = context_seq(tok);
      on_io([seq](Core& c) { c.on_ack(seq, true); });
    };
    publish_listener.failure = [this](const mqtt::token& tok) {
      const std::uint64_t seq = context_seq(tok);
      on_io([seq](Core& c) { c.on_ack(seq, false); });
    };
    try_connect();
    next_status = Clock::now() + status_period();
    arm_status();
    arm_pump();
  }

  Clock::duration status_period() const {
    return std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / cfg.status_hz));
  }

  void arm_status() {
    status_timer.expires_at(next_status);
    status_timer.async_wait([w = weak_from_this()](const boost::system::error_code& ec) {
      auto c = w.lock();
      if (ec || !c || c->stopped) return;
      c->on_status_tick();
    });
  }

  void arm_pump() {
    pump_timer.expires_after(kPumpPeriod);
    pump_timer.async_wait([w = weak_from_this()](const boost::system::error_code& ec) {
      auto c = w.lock();
      if (ec || !c || c->stopped) return;
      c->pump();
      c->arm_pump();
    });
  }

  void try_connect() {
    if (stopped || up || connecting) return;
    connecting = true;
    try {
      client->connect(connect_opts, nullptr, connect_listener);
    } catch (const std::exception& e) {
      connecting = false;
      std::cerr << "ncd serve: MQTT: cannot start connecting to " << cfg.broker << ": " << e.what()
                << '\n';
      schedule_reconnect();
    }
  }

  void schedule_reconnect() {
    if (stopped) return;
    const double delay_s =
        std::min(cfg.reconnect_max_s, cfg.reconnect_min_s * std::pow(2.0, std::min(attempts, 30)));
    ++attempts;
    reconnect_timer.expires_after(
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(delay_s)));
    reconnect_timer.async_wait([w = weak_from_this()](const boost::system::error_code& ec) {
      auto c = w.lock();
      if (ec || !c || c->stopped) return;
      c->try_connect();
    });
  }

  void on_connect_failed(int rc) {
    connecting = false;
    if (up) return;
    ++connect_failures;
    const std::string why = connect_failure_text(rc, cfg.tls());
    {
      const std::lock_guard lock(failure_mutex);
      last_failure = why;
    }
    if (attempts == 0 || (attempts & (attempts - 1)) == 0) {  // the 1st, 2nd, 4th, 8th... only
      std::cerr << "ncd serve: MQTT: cannot connect to " << cfg.broker << " (" << why
                << "); trying again with backoff up to " << cfg.reconnect_max_s << " s\n";
    }
    schedule_reconnect();
  }

  void on_connected() {
    connecting = false;
    up = true;
    attempts = 0;
    ++connects;
    reconnect_timer.cancel();
    std::cerr << "ncd serve: MQTT: connected to " << cfg.broker << ", topics " << cfg.topic_root
              << "...\n";
    try {
      client->subscribe(t_cmd, 1);
      json online{{"online", true},
                  {"client_id", cfg.client_id},
                  {"status_hz", cfg.status_hz},
                  {"time_unix_s", unix_time_s()}};
      if (!cfg.page_url.empty()) online["page_url"] = cfg.page_url;
      client->publish(t_online, online.dump(), 1, true);
    } catch (const std::exception& e) {
      std::cerr << "ncd serve: MQTT: " << e.what() << '\n';
    }
    last_state.clear();  // the broker may have restarted without its retained messages
    publish_status();
    pump();
  }

  void on_lost(const std::string& cause) {
    up = false;
    ++losses;
    for (Pending& p : inflight) p.sent = false;
    std::cerr << "ncd serve: MQTT: connection to " << cfg.broker << " lost"
              << (cause.empty() ? "" : " (" + cause + ")") << "; " << inflight.size() + ring.size()
              << " events wait (bound " << cfg.queue_bound << " + " << cfg.queue_bound << ")\n";
    schedule_reconnect();
  }

  void on_ack(std::uint64_t seq, bool ok) {
    const auto it = std::lower_bound(inflight.begin(), inflight.end(), seq,
                                     [](const Pending& p, std::uint64_t s) { return p.seq < s; });
    if (it == inflight.end() || it->seq != seq) return;
    if (ok) {
      it->acked = true;
    } else {
      it->sent = false;  // sent again by the next pump while connected
    }
    while (!inflight.empty() && inflight.front().acked) {
      inflight.pop_front();
      ++published;
    }
  }

  bool send(Pending& p) {
    try {
      client->publish(t_events, p.payload.data(), p.payload.size(), 1, false, seq_context(p.seq),
                      publish_listener);
    } catch (const std::exception&) {
      return false;  // not connected, or Paho's queue is full: the next pump tries again
    }
    if (p.was_sent) ++resent;
    p.sent = p.was_sent = true;
    return true;
  }

  void pump() {
    if (!up) return;
    for (Pending& p : inflight) {
      if (!p.sent && !p.acked && !send(p)) return;
    }
    QueuedEvent e;
    while (inflight.size() < cfg.queue_bound && ring.pop(e)) {
      json ev = e.event.is_object() ? std::move(e.event) : json{{"value", std::move(e.event)}};
      ev["seq"] = e.seq;
      inflight.push_back(Pending{e.seq, ev.dump(), false, false, false});
      if (!send(inflight.back())) return;
    }
  }

  void on_status_tick() {
    publish_status();
    const auto now = Clock::now();
    next_status += status_period();
    if (next_status <= now) next_status = now + status_period();
    arm_status();
  }

  void publish_status() {
    if (!up) return;
    json s;
    try {
      s = status_fn();
    } catch (const std::exception& e) {
      std::cerr << "ncd serve: MQTT: the status failed: " << e.what() << '\n';
      return;
    }
    if (!s.is_object()) return;
    s.erase("ok");
    // Units in the names: the socket's "position" is in mm.
    if (const auto p = s.find("position"); p != s.end() && !s.contains("position_mm")) {
      s["position_mm"] = std::move(*p);
      s.erase("position");
    }
    const std::string state =
        s.contains("state") && s["state"].is_string() ? s["state"].get<std::string>() : "";
    try {
      if (state != last_state) {
        client->publish(t_state,
                        json{{"state", state},
                             {"job", s.contains("job") ? s["job"] : json()},
                             {"time_unix_s", unix_time_s()}}
                            .dump(),
                        1, true);
        last_state = state;
        ++state_n;
      }
      s["time_s"] = std::chrono::duration<double>(Clock::now() - t0).count();
      s["time_unix_s"] = unix_time_s();
      s["events_dropped"] = dropped.load();
      s["events_waiting"] = ring.size() + inflight.size();
      client->publish(t_status, s.dump(), 0, false);
      ++status_n;
    } catch (const std::exception&) {
      // not connected any more: the connection-lost handler follows
    }
  }

  void on_command(const std::string& payload) {
    ++commands;
    json reply;
    json id;
    if (payload.size() > options.max_line_bytes) {
      reply = error_reply("the command has " + std::to_string(payload.size()) +
                          " bytes, the limit is " + std::to_string(options.max_line_bytes) +
                          "; send a shorter one");
    } else {
      comms::RequestCheck check = comms::check_request(payload, options);
      if (check.subscribe_hz) {
        reply = error_reply("\"subscribe\" is for the control socket; over MQTT the status is on " +
                            t_status);
      } else if (!check.to_handler) {
        reply = std::move(check.reply);
        id = request_id(payload);
      } else {
        if (const auto it = check.request.find("id"); it != check.request.end()) {
          id = *it;
          check.request.erase(it);
        }
        reply = call_handler(check.request);
      }
    }
    if (!id.is_null()) reply["id"] = id;
    try {
      client->publish(t_reply, reply.dump(), 1, false);
    } catch (const std::exception& e) {
      std::cerr << "ncd serve: MQTT: cannot publish a reply: " << e.what() << '\n';
    }
  }

  // As the control socket does (comms::handler_reply).
  json call_handler(const json& request) { return comms::handler_reply(command_fn, request); }

  void stop(double timeout_s) {
    if (stopped) return;
    stopped = true;
    status_timer.cancel();
    pump_timer.cancel();
    reconnect_timer.cancel();
    const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(
        std::chrono::duration<double>(timeout_s));
    try {
      if (up) {
        client->publish(t_online, offline_payload(), 1, true)->wait_for(wait);
        client->disconnect(static_cast<int>(wait.count()))->wait_for(wait);
      }
    } catch (const std::exception&) {
      // the broker went away meanwhile: its last will says offline
    }
    up = false;
    try {
      client->disable_callbacks();
    } catch (const std::exception&) {
      // A connection attempt is under way (Paho refuses then): destroying the client ends it,
      // and until then the callbacks only post to the io_context through a weak pointer.
    }
  }

  boost::asio::io_context& io;
  MqttConfig cfg;
  StatusFn status_fn;
  CommandFn command_fn;
  comms::ServerOptions options;
  std::string t_status, t_state, t_events, t_online, t_cmd, t_reply;
  mqtt::connect_options connect_opts;
  Listener connect_listener, publish_listener;
  boost::asio::steady_timer status_timer, pump_timer, reconnect_timer;
  EventRing ring;
  std::deque<Pending> inflight;  // ordered by seq
  std::atomic<bool> up{false};
  bool started = false, stopped = false, connecting = false;
  int attempts = 0;
  std::string last_state;
  Clock::time_point t0{}, next_status{};
  std::atomic<std::uint64_t> next_seq{1}, dropped{0};
  std::atomic<std::uint64_t> published{0}, resent{0}, status_n{0}, state_n{0}, commands{0},
      connects{0}, losses{0}, connect_failures{0};
  mutable std::mutex failure_mutex;
  std::string last_failure;  // guarded by failure_mutex
  // Last, so destroyed first: while Paho winds down (and may still call back) every member it
  // can reach, the listeners included, is alive.
  std::unique_ptr<mqtt::async_client> client;
};

MqttBridge::MqttBridge(boost::asio::io_context& io, const MqttConfig& config, StatusFn status,
                       CommandFn command, std::optional<std::string> token)
    : core_(std::make_shared<Core>(io, config, std::move(status), std::move(command),
                                   std::move(token))) {}

MqttBridge::~MqttBridge() {
  stop();
}

void MqttBridge::start() {
  core_->start();
}

void MqttBridge::stop(double timeout_s) {
  core_->stop(timeout_s);
}

bool MqttBridge::push_event(json event) {
  Core& c = *core_;
  const std::uint64_t seq = c.next_seq.fetch_add(1, std::memory_order_relaxed);
  if (c.ring.push(QueuedEvent{seq, std::move(event)})) return true;
  c.dropped.fetch_add(1, std::memory_order_relaxed);
  return false;
}

BridgeCounters MqttBridge::counters() const {
  const Core& c = *core_;
  BridgeCounters n;
  n.events_pushed = c.next_seq.load() - 1;
  n.events_dropped = c.dropped.load();
  n.events_published = c.published.load();
  n.events_resent = c.resent.load();
  n.status_published = c.status_n.load();
  n.state_published = c.state_n.load();
  n.commands = c.commands.load();
  n.connects = c.connects.load();
  n.connection_losses = c.losses.load();
  n.connect_failures = c.connect_failures.load();
  return n;
}

std::string MqttBridge::last_failure() const {
  const std::lock_guard lock(core_->failure_mutex);
  return core_->last_failure;
}

bool MqttBridge::connected() const {
  return core_->up.load();
}

}  // namespace ncd::api
