// `ncd bench latency --with-service-io`: does the dashboard and the MQTT bridge make the cycle
// wake later? One run, one process, on one machine, as `ncd serve` is put together:
//
//   io thread (the service's io_context)                         cycle thread (SCHED_FIFO)
//   ┌───────────────────────────────────────────────────┐ ring  ┌──────────────────────┐
//   │ service::Service::poll() every 1 ms (app/service)  │ ◄──── │ planner + walker     │
//   │ [with] WebServer ── WebSocket ──► reader thread    │       │ on a spiral NURBS    │
//   │ [with] MqttBridge ── status at R Hz ──► mosquitto ─┼──► subscriber (Paho, counts) │
//   │ [with] EventFeed: the service's events to both     │       └──────────────────────┘
//   └───────────────────────────────────────────────────┘
//
// A phase is one job of the service library (the spiral of `ncd bench latency`, default machine
// limits) started, run for --seconds and stopped (a jerk-limited stop); its lateness is the
// cycle's own histogram (motion::CycleStats, every wake-up). "without": nothing but the service
// loop drains the setpoints. "with": before the job starts, the web server listens with a
// WebSocket client connected at R status frames per second (the reader thread reads and parses
// every frame the server serialised and sent: status, events), and the MQTT bridge publishes
// status at R Hz to a real broker where a subscriber counts what arrives; observers and client
// are torn down after the job's cycle has ended, outside the measurement.
//
// Phases alternate, and each round swaps the order of the two (without, with, with, without, …):
// a steady drift of the machine's load over the run weighs on both kinds alike. The phases of a
// kind are summed (their histograms merged) and the report gives p50, p99, max of each kind and
// p99(with) / p99(without) against the issue's limit 1.1, with the load average before and after.
// Frames and messages are counted only while the job runs, so that they can be set against the
// rate: R × the phase's time.
#include "app/bench_service_io.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <mqtt/async_client.h>
#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "api/event_feed.hpp"
#include "api/intake.hpp"
#include "api/mqtt_bridge.hpp"
#include "api/web_server.hpp"
#include "app/latency_report.hpp"
#include "core/error.hpp"
#include "core/output_file.hpp"
#include "geometry/spiral.hpp"
#include "service/service.hpp"

extern char** environ;

namespace ncd::app {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
using Clock = std::chrono::steady_clock;
using Json = nlohmann::ordered_json;

constexpr int kMaxRounds = 100;
constexpr auto kConnectTimeout = std::chrono::seconds(10);

// "0.52 0.61 0.70" from /proc/loadavg (1, 5, 15 minutes); "" where there is none.
std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  if (!(in >> a >> b >> c)) return "";
  return a + " " + b + " " + c;
}

std::string find_mosquitto() {
  for (const char* p : {"/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto", "/usr/bin/mosquitto",
                        "/sbin/mosquitto"}) {
    if (::access(p, X_OK) == 0) return p;
  }
  return "";
}

// A TCP port on 127.0.0.1 free a moment ago (the kernel's choice).
int free_loopback_port() {
  asio::io_context io;
  asio::ip::tcp::acceptor a(io, asio::ip::tcp::endpoint(asio::ip::address_v4::loopback(), 0));
  return a.local_endpoint().port();
}

bool port_accepts(int port) {
  asio::io_context io;
  asio::ip::tcp::socket s(io);
  boost::system::error_code ec;
  s.connect(
      asio::ip::tcp::endpoint(asio::ip::address_v4::loopback(), static_cast<unsigned short>(port)),
      ec);
  return !ec;
}

// mosquitto on a free loopback port, anonymous clients allowed (loopback only), its log in a
// private folder removed at the end; SIGTERM and a wait in the destructor.
class OwnBroker {
 public:
  OwnBroker() {
    const std::string exe = find_mosquitto();
    if (exe.empty()) {
      throw InputError(
          "--with-service-io needs an MQTT broker: mosquitto is not installed and no "
          "--mqtt-broker URL was given; apt-get install mosquitto, or give "
          "--mqtt-broker tcp://HOST:PORT");
    }
    std::string dir = (std::filesystem::temp_directory_path() / "ncd-bench-XXXXXX").string();
    if (::mkdtemp(dir.data()) == nullptr) {
      throw InputError("cannot create a folder for the broker's config " + dir + ": " +
                       std::strerror(errno) + "; set TMPDIR to a writable directory");
    }
    dir_ = dir;
    port_ = free_loopback_port();
    const std::string conf = (dir_ / "mosquitto.conf").string();
    std::ofstream(conf) << "listener " << port_ << " 127.0.0.1\n"
                        << "allow_anonymous true\n"
                        << "persistence false\n"
                        << "log_dest stderr\n";
    const std::string log = (dir_ / "mosquitto.log").string();
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    std::vector<std::string> args = {exe, "-c", conf};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, exe.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) {
      pid_ = -1;
      cleanup();
      throw InputError("cannot start " + exe + ": " + std::strerror(rc) +
                       "; give a running broker with --mqtt-broker tcp://HOST:PORT");
    }
    const auto end = Clock::now() + kConnectTimeout;
    while (!port_accepts(port_)) {
      int status = 0;
      if (Clock::now() > end || ::waitpid(pid_, &status, WNOHANG) == pid_) {
        std::ifstream in(log);
        const std::string text(std::istreambuf_iterator<char>(in), {});
        cleanup();
        throw InputError("mosquitto did not accept connections on 127.0.0.1:" +
                         std::to_string(port_) + " within 10 s (its log: " + text +
                         "); give a running broker with --mqtt-broker tcp://HOST:PORT");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  ~OwnBroker() { cleanup(); }
  OwnBroker(const OwnBroker&) = delete;
  OwnBroker& operator=(const OwnBroker&) = delete;
  std::string url() const { return "tcp://127.0.0.1:" + std::to_string(port_); }

 private:
  void cleanup() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      int status = 0;
      ::waitpid(pid_, &status, 0);
      pid_ = -1;
    }
    std::error_code ignored;
    if (!dir_.empty()) std::filesystem::remove_all(dir_, ignored);
  }
  std::filesystem::path dir_;
  int port_ = 0;
  pid_t pid_ = -1;
};

// What a client of the observers received: frames or messages by kind.
struct Received {
  std::atomic<std::int64_t> status{0}, events{0}, state{0}, other{0}, bytes{0};
};
struct ReceivedCount {
  std::int64_t status = 0, events = 0, state = 0, other = 0, bytes = 0;
};
ReceivedCount snapshot(const Received& r) {
  return {r.status.load(), r.events.load(), r.state.load(), r.other.load(), r.bytes.load()};
}
ReceivedCount operator-(const ReceivedCount& a, const ReceivedCount& b) {
  return {a.status - b.status, a.events - b.events, a.state - b.state, a.other - b.other,
          a.bytes - b.bytes};
}

// The page's stand-in: a WebSocket client on its own thread that reads every frame the server
// sends and parses it as the page does (status, event, program, reply).
class WsReader {
 public:
  explicit WsReader(std::uint16_t port) {
    thread_ = std::thread([this, port] { run(port); });
  }
  ~WsReader() { join(); }
  WsReader(const WsReader&) = delete;
  WsReader& operator=(const WsReader&) = delete;
  const Received& received() const { return received_; }
  // Ends when the server closes the WebSocket.
  void join() {
    if (thread_.joinable()) thread_.join();
  }
  std::string error() const {
    std::lock_guard lock(mutex_);
    return error_;
  }

 private:
  void run(std::uint16_t port) {
    try {
      asio::io_context io;
      beast::websocket::stream<asio::ip::tcp::socket> ws(io);
      ws.next_layer().connect(asio::ip::tcp::endpoint(asio::ip::address_v4::loopback(), port));
      ws.handshake("127.0.0.1:" + std::to_string(port), "/ws");
      for (;;) {
        beast::flat_buffer buffer;
        beast::error_code ec;
        ws.read(buffer, ec);
        if (ec) return;  // the server closed the page (WebServer::close) or went away
        const std::string text = beast::buffers_to_string(buffer.data());
        received_.bytes += static_cast<std::int64_t>(text.size());
        const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
        if (j.is_object() && j.contains("status")) {
          ++received_.status;
        } else if (j.is_object() && j.contains("event")) {
          ++received_.events;
        } else {
          ++received_.other;
        }
      }
    } catch (const std::exception& e) {
      std::lock_guard lock(mutex_);
      error_ = e.what();
    }
  }
  Received received_;
  mutable std::mutex mutex_;
  std::string error_;
  std::thread thread_;
};

// A watching screen on the broker: subscribes to the machine's topics and counts by topic.
class MqttCounter {
 public:
  MqttCounter(const std::string& url, const std::string& root)
      : client_(url, "ncd-bench-watch-" + std::to_string(::getpid()),
                static_cast<mqtt::iclient_persistence*>(nullptr)),
        root_(root) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      const std::string& topic = m->get_topic();
      const std::string leaf = topic.substr(std::min(topic.size(), root_.size()));
      received_.bytes += static_cast<std::int64_t>(m->get_payload().size());
      if (leaf == "status") {
        ++received_.status;
      } else if (leaf == "events") {
        ++received_.events;
      } else if (leaf == "state") {
        ++received_.state;
      } else {
        ++received_.other;
      }
    });
    auto opts = mqtt::connect_options_builder().clean_session(true).finalize();
    try {
      if (!client_.connect(opts)->wait_for(kConnectTimeout)) throw std::runtime_error("timeout");
      if (!client_.subscribe(root_ + "#", 0)->wait_for(kConnectTimeout)) {
        throw std::runtime_error("subscribe timed out");
      }
    } catch (const std::exception& e) {
      throw InputError("the bench's subscriber cannot use the broker " + url + " (" + e.what() +
                       "); give a broker that takes anonymous clients with --mqtt-broker, or "
                       "leave it out and the bench starts mosquitto");
    }
  }
  ~MqttCounter() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (const std::exception&) {
      // the broker went away: nothing to say goodbye to
    }
  }
  MqttCounter(const MqttCounter&) = delete;
  MqttCounter& operator=(const MqttCounter&) = delete;
  const Received& received() const { return received_; }

 private:
  mqtt::async_client client_;
  std::string root_;
  Received received_;
};

// The ControlHandler the web server serves: the service library's status as `ncd serve` sends it
// (api::to_json); requests other than status are refused (the bench drives the job itself).
class StatusOnly : public comms::ControlHandler {
 public:
  explicit StatusOnly(service::Service& core) : core_(core) {}
  nlohmann::json handle(const nlohmann::json& request) override {
    if (request.value("cmd", "") == "status") return status();
    throw InputError("the bench's service takes status requests only");
  }
  nlohmann::json status() override { return api::to_json(core_.status()); }

 private:
  service::Service& core_;
};

// Runs f on the io_context's thread and waits for its result (or its exception).
template <class F>
auto on_io(asio::io_context& io, F f) -> decltype(f()) {
  std::packaged_task<decltype(f())()> task(std::move(f));
  auto result = task.get_future();
  asio::post(io, [&task] { task(); });
  return result.get();
}

// service::Service::poll() every 1 ms while a job runs, as app::Service's loop.
class PollLoop {
 public:
  PollLoop(asio::io_context& io, service::Service& core) : timer_(io), core_(core) {}
  void arm() {
    timer_.expires_after(std::chrono::milliseconds(1));
    timer_.async_wait([this](const boost::system::error_code& ec) {
      if (!ec && core_.poll()) arm();
    });
  }

 private:
  asio::steady_timer timer_;
  service::Service& core_;
};

// The observers of one "with" phase and the page's reader, made and destroyed on the io thread
// (the reader on its own): torn down in the destructor too, when a phase fails.
struct Observers {
  explicit Observers(asio::io_context& io_context) : io(io_context) {}
  ~Observers() { teardown(); }
  Observers(const Observers&) = delete;
  Observers& operator=(const Observers&) = delete;

  // Closes the page (its WebSocket ends at the next status tick, and the reader with it), then
  // says goodbye to the broker and destroys the observers. Idempotent.
  void teardown() {
    if (!web && !bridge && !feed) return;
    on_io(io, [this] {
      if (feed) feed->close();
      if (web) web->close();
    });
    if (reader) {
      reader->join();
      reader_error = reader->error();
    }
    on_io(io, [this] {
      if (bridge) bridge->stop();
      feed.reset();
      web.reset();
      bridge.reset();
    });
  }

  asio::io_context& io;
  std::unique_ptr<StatusOnly> handler;
  std::unique_ptr<api::MqttBridge> bridge;
  std::unique_ptr<api::WebServer> web;
  std::unique_ptr<api::EventFeed> feed;
  std::unique_ptr<WsReader> reader;
  std::string reader_error;
};

struct PhaseResult {
  bool with = false;
  motion::CycleStats stats;
  double job_s = 0.0;  // from start to the end of the stop ramp
  ReceivedCount ws, mqtt;
  api::BridgeCounters bridge;
  std::string ws_error;
};

struct KindSum {
  motion::CycleStats stats;
  double job_s = 0.0;
  int phases = 0;
};

Json received_json(const ReceivedCount& r, double job_s) {
  return {{"status", r.status},
          {"events", r.events},
          {"state", r.state},
          {"other", r.other},
          {"bytes", r.bytes},
          {"status_per_s", job_s > 0.0 ? static_cast<double>(r.status) / job_s : 0.0}};
}

Json kind_json(const KindSum& k) {
  Json j;
  j["phases"] = k.phases;
  j["job_s"] = k.job_s;
  j["periods"] = k.stats.periods;
  j["lateness_us"] = percentiles_json(percentiles_us_from_ns(k.stats.lateness_ns));
  Json bins = Json::array();
  for (const HistogramBin& b : histogram_bins_us(k.stats.lateness_ns)) {
    bins.push_back({{"from_us", b.from_us}, {"to_us", b.to_us}, {"count", b.count}});
  }
  j["lateness_histogram"] = bins;
  j["late_wakeups"] = k.stats.late_wakeups;
  j["caught_up_periods"] = k.stats.caught_up;
  j["overruns"] = k.stats.overruns;
  j["setpoints_lost"] = k.stats.setpoints_lost;
  j["compute_us"] = {{"median", k.stats.compute_ns.quantile(0.5) * 1e-3},
                     {"p99", k.stats.compute_ns.quantile(0.99) * 1e-3},
                     {"max", k.stats.compute_ns.max() * 1e-3}};
  return j;
}

void check_args(const ServiceIoBenchArgs& a) {
  if (a.seconds <= 0) throw InputError("--seconds must be > 0, got " + std::to_string(a.seconds));
  if (a.rounds < 1 || a.rounds > kMaxRounds) {
    throw InputError("--rounds " + std::to_string(a.rounds) + " is outside 1.." +
                     std::to_string(kMaxRounds) +
                     "; each round is one phase without and one with the observers");
  }
  if (!(a.period_ms >= 0.01 && a.period_ms <= 1000.0)) {
    throw InputError("--period-ms " + std::to_string(a.period_ms) +
                     " is outside 0.01..1000 ms; give the cycle's period in milliseconds");
  }
  if (!(a.status_hz >= api::HttpLimits::kMinStatusHz &&
        a.status_hz <= api::HttpLimits::kMaxStatusHz)) {
    throw InputError("--status-hz " + std::to_string(a.status_hz) + " is outside " +
                     format_us(api::HttpLimits::kMinStatusHz) + ".." +
                     format_us(api::HttpLimits::kMaxStatusHz) +
                     " (the dashboard's status rates); give the rate of the page and of MQTT");
  }
}

// What every phase shares: the broker and the topics, the rate, and the job.
struct PhaseSetup {
  std::string broker, root;
  bool own_broker = false;  // mosquitto started by the bench
  double status_hz = 0.0;
  int seconds = 0;
  motion::JobConfig job_cfg;  // default machine limits and cutting parameters
  int turns = 1;
  std::shared_ptr<const toolpath::Path> path;
};

// The spiral of one phase: turns for one phase at the machine's maximum feed, with half again
// as margin (as the plain bench's spiral); a job that ends early only shortens its phase.
void size_the_job(PhaseSetup& p, double period_ms) {
  p.job_cfg.limits.period_s = period_ms * 1e-3;
  const double needed_mm = 1.5 * p.seconds * p.job_cfg.limits.max_feed_mm_per_min / 60.0 + 1000.0;
  p.turns = 1;
  while (p.turns < 900 && toolpath::spiral_length_mm(p.turns) < needed_mm) ++p.turns;
  p.path = std::make_shared<const toolpath::Path>(toolpath::spiral_path(p.turns));
}

void print_header(const ServiceIoBenchArgs& a, const PhaseSetup& p,
                  const std::string& load_before) {
  std::printf(
      "ncd bench latency --with-service-io: %d round%s of %d s per phase at a %s ms period, "
      "spiral NURBS of %d turns, default machine limits\n"
      "  with: the dashboard's WebSocket read by a client at %s status frames/s, MQTT status at "
      "%s Hz to %s%s\n"
      "  load average before: %s\n",
      a.rounds, a.rounds == 1 ? "" : "s", a.seconds, format_us(a.period_ms).c_str(), p.turns,
      format_us(a.status_hz).c_str(), format_us(a.status_hz).c_str(), p.broker.c_str(),
      p.own_broker ? " (mosquitto, started by the bench)" : "", load_before.c_str());
  std::fflush(stdout);
}

// The service as `ncd serve` holds it: its io_context on a thread of its own, poll() every
// 1 ms while a job runs; the destructor stops the io thread and joins it.
struct ServiceOnIo {
  ServiceOnIo() : work(asio::make_work_guard(io)), core(options()), loop(io, core) {
    thread = std::thread([this] {
      for (;;) {
        try {
          io.run();
          return;
        } catch (const std::exception& e) {
          std::fprintf(stderr, "ncd bench: internal error on the io thread: %s\n", e.what());
        }
      }
    });
  }
  ~ServiceOnIo() {
    work.reset();
    io.stop();
    if (thread.joinable()) thread.join();
  }
  ServiceOnIo(const ServiceOnIo&) = delete;
  ServiceOnIo& operator=(const ServiceOnIo&) = delete;
  static service::ServiceOptions options() {
    service::ServiceOptions so;
    so.clock = motion::ClockKind::Wall;
    so.realtime = true;
    return so;
  }

  asio::io_context io;
  asio::executor_work_guard<asio::io_context::executor_type> work;
  service::Service core;
  PollLoop loop;
  std::thread thread;
};

// A "with" phase's observers, made on the io thread: the MQTT bridge, the web server and the
// event feed to both; then the page's reader; both at work before the job starts (a status
// frame read, the bridge up).
void start_observers(ServiceOnIo& s, const MqttCounter& watcher, const PhaseSetup& p,
                     Observers& obs) {
  on_io(s.io, [&] {
    obs.handler = std::make_unique<StatusOnly>(s.core);
    api::MqttConfig mc;
    mc.broker = p.broker;
    mc.client_id = "ncd-bench-" + std::to_string(::getpid());
    mc.topic_root = p.root;
    mc.status_hz = p.status_hz;
    StatusOnly& h = *obs.handler;
    obs.bridge = std::make_unique<api::MqttBridge>(
        s.io, mc, [&h] { return h.status(); },
        [&h](const nlohmann::json& req) { return h.handle(req); });
    obs.bridge->start();
    api::HttpConfig hc;
    hc.listen = "tcp:127.0.0.1:0";
    hc.status_hz = p.status_hz;
    obs.web =
        std::make_unique<api::WebServer>(s.io, hc, h, std::nullopt, toolpath::InterpretOptions{});
    obs.feed = std::make_unique<api::EventFeed>(s.io, s.core.subscribe(api::EventFeed::kCapacity));
    api::MqttBridge& b = *obs.bridge;
    api::WebServer& w = *obs.web;
    obs.feed->add_sink([&b](const nlohmann::json& e) { b.push_event(e); });
    obs.feed->add_sink([&w](const nlohmann::json& e) { w.push_event(e); });
    obs.feed->start();
  });
  obs.reader = std::make_unique<WsReader>(obs.web->port());
  const WsReader* reader = obs.reader.get();
  const auto end = Clock::now() + kConnectTimeout;
  while (reader->received().status.load() == 0 || !obs.bridge->connected() ||
         watcher.received().status.load() == 0) {
    if (Clock::now() > end) {
      throw InputError("the observers did not start within 10 s (WebSocket frames " +
                       std::to_string(reader->received().status.load()) + ", MQTT bridge " +
                       (obs.bridge->connected() ? "up" : "down") +
                       (reader->error().empty() ? "" : ", " + reader->error()) +
                       "); check the broker " + p.broker);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

// Submits and starts the job, lets it run for the phase's seconds (or to its end), stops it
// and waits until the stop ramp is over; the first start's realtime grant goes to `realtime`.
void run_job(ServiceOnIo& s, const PhaseSetup& p, std::string& realtime, Clock::time_point t0) {
  on_io(s.io, [&] {
    service::JobSpec job;
    job.name = "bench spiral";
    job.path = p.path;
    job.motion = p.job_cfg;
    job.rules = service::LiveLimitRules::from(p.job_cfg.limits);
    s.core.submit(std::move(job));
    const std::string grant = s.core.start();
    if (realtime.empty()) realtime = grant;
    s.loop.arm();
  });
  const auto deadline = t0 + std::chrono::seconds(p.seconds);
  while (Clock::now() < deadline && on_io(s.io, [&] { return s.core.busy(); })) {
    std::this_thread::sleep_until(std::min(deadline, Clock::now() + std::chrono::milliseconds(50)));
  }
  on_io(s.io, [&] {
    if (s.core.busy()) s.core.stop("the bench's phase is over");
  });
  while (on_io(s.io, [&] { return s.core.busy(); })) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

void print_phase(const PhaseResult& r, std::size_t number) {
  const LatencyPercentiles p = percentiles_us_from_ns(r.stats.lateness_ns);
  std::printf("phase %zu %-7s %6.2f s, %lld periods: lateness p50 %s, p99 %s, max %s us", number,
              r.with ? "with" : "without", r.job_s, static_cast<long long>(r.stats.periods),
              format_us(p.p50_us).c_str(), format_us(p.p99_us).c_str(),
              format_us(p.max_us).c_str());
  if (r.with) {
    std::printf(
        "; WebSocket %lld status + %lld event frames, MQTT %lld status + %lld event "
        "messages",
        static_cast<long long>(r.ws.status), static_cast<long long>(r.ws.events),
        static_cast<long long>(r.mqtt.status), static_cast<long long>(r.mqtt.events));
  }
  std::printf("\n");
  std::fflush(stdout);
}

// One phase, with or without the observers; its line on stdout (phase `number`).
PhaseResult run_phase(ServiceOnIo& s, const MqttCounter& watcher, const PhaseSetup& p, bool with,
                      std::string& realtime, std::size_t number) {
  PhaseResult r;
  r.with = with;
  Observers obs(s.io);
  if (with) start_observers(s, watcher, p, obs);
  const ReceivedCount ws0 = obs.reader ? snapshot(obs.reader->received()) : ReceivedCount{};
  const ReceivedCount mq0 = snapshot(watcher.received());
  const auto t0 = Clock::now();
  run_job(s, p, realtime, t0);
  r.job_s = std::chrono::duration<double>(Clock::now() - t0).count();
  if (obs.reader) r.ws = snapshot(obs.reader->received()) - ws0;
  r.mqtt = snapshot(watcher.received()) - mq0;
  const service::Status st = on_io(s.io, [&] { return s.core.status(); });
  if (st.state == service::State::Error) {
    throw std::runtime_error("the bench's job ended in error: " + st.error);
  }
  r.stats = on_io(s.io, [&] {
    const motion::CycleStats* stats = s.core.cycle_stats();
    if (stats == nullptr) throw std::runtime_error("the bench's job has no cycle statistics");
    return *stats;
  });
  if (with) {
    r.bridge = obs.bridge->counters();
    obs.teardown();
    r.ws_error = obs.reader_error;
  }
  print_phase(r, number);
  return r;
}

// The phases of each kind summed, and p99(with) / p99(without) against the limit.
struct IoSummary {
  KindSum without, with;
  LatencyPercentiles p0, p1;
  std::optional<double> ratio;
  bool within = false;
  std::int64_t lost = 0;
};

IoSummary summarise(const std::vector<PhaseResult>& phases) {
  IoSummary s;
  for (const PhaseResult& r : phases) {
    KindSum& k = r.with ? s.with : s.without;
    add_stats(k.stats, r.stats);
    k.job_s += r.job_s;
    ++k.phases;
  }
  s.p0 = percentiles_us_from_ns(s.without.stats.lateness_ns);
  s.p1 = percentiles_us_from_ns(s.with.stats.lateness_ns);
  if (s.p0.p99_us > 0.0) s.ratio = s.p1.p99_us / s.p0.p99_us;
  s.within = s.ratio && *s.ratio <= kServiceIoP99RatioLimit;
  s.lost = s.without.stats.setpoints_lost + s.with.stats.setpoints_lost;
  return s;
}

// What the run saw besides the phases: the realtime grant and the load average.
struct RunNotes {
  std::string realtime, load_before, load_after;
};

void print_summary(const IoSummary& s, const RunNotes& n) {
  std::printf("realtime: %s\n", n.realtime.c_str());
  std::printf("\n%s", format_latency_table({{"without", s.p0}, {"with page+MQTT", s.p1}}).c_str());
  if (s.ratio) {
    std::printf("p99 with / without = %.3f (limit %.2g): %s\n", *s.ratio, kServiceIoP99RatioLimit,
                s.within ? "within the limit" : "above the limit");
  } else {
    std::printf("p99 with / without: no ratio (p99 without is %s us)\n",
                format_us(s.p0.p99_us).c_str());
  }
  std::printf("load average before %s, after %s\n", n.load_before.c_str(), n.load_after.c_str());
  std::printf("setpoints lost: %lld\n", static_cast<long long>(s.lost));
  std::fflush(stdout);
}

Json phase_json(const PhaseResult& r) {
  Json p;
  p["kind"] = r.with ? "with" : "without";
  p["job_s"] = r.job_s;
  p["periods"] = r.stats.periods;
  p["lateness_us"] = percentiles_json(percentiles_us_from_ns(r.stats.lateness_ns));
  p["overruns"] = r.stats.overruns;
  p["setpoints_lost"] = r.stats.setpoints_lost;
  if (r.with) {
    p["websocket_frames"] = received_json(r.ws, r.job_s);
    p["websocket_error"] = r.ws_error.empty() ? Json() : Json(r.ws_error);
    p["mqtt_messages"] = received_json(r.mqtt, r.job_s);
    p["bridge"] = {{"status_published", r.bridge.status_published},
                   {"events_published", r.bridge.events_published},
                   {"events_dropped", r.bridge.events_dropped}};
  } else {
    p["websocket_frames"] = nullptr;
    p["mqtt_messages"] = received_json(r.mqtt, r.job_s);
  }
  return p;
}

Json run_json(const ServiceIoBenchArgs& a, const PhaseSetup& p, const RunNotes& n,
              const std::vector<PhaseResult>& phases, const IoSummary& s) {
  Json j;
  j["mode"] = "with_service_io";
  j["seconds_per_phase"] = a.seconds;
  j["rounds"] = a.rounds;
  j["period_ms"] = a.period_ms;
  j["status_hz"] = a.status_hz;
  j["broker"] = {{"url", p.broker}, {"started_by_bench", p.own_broker}};
  j["realtime"] = n.realtime;
  j["load_average_before"] = n.load_before;
  j["load_average_after"] = n.load_after;
  Json list = Json::array();
  for (const PhaseResult& r : phases) list.push_back(phase_json(r));
  j["phases"] = list;
  j["without"] = kind_json(s.without);
  j["with"] = kind_json(s.with);
  j["p99_ratio"] = s.ratio ? Json(*s.ratio) : Json();
  j["p99_ratio_limit"] = kServiceIoP99RatioLimit;
  j["p99_within_limit"] = s.ratio ? Json(s.within) : Json();
  return j;
}

}  // namespace

int run_bench_service_io(const ServiceIoBenchArgs& a) {
  check_args(a);
  RunNotes notes;
  notes.load_before = load_average();
  PhaseSetup setup;
  std::unique_ptr<OwnBroker> own_broker;
  setup.broker = a.broker;
  if (setup.broker.empty()) {
    own_broker = std::make_unique<OwnBroker>();
    setup.broker = own_broker->url();
  }
  setup.own_broker = own_broker != nullptr;
  setup.root = "ncd/bench/" + std::to_string(::getpid()) + "/";
  setup.status_hz = a.status_hz;
  setup.seconds = a.seconds;
  MqttCounter watcher(setup.broker, setup.root);
  size_the_job(setup, a.period_ms);
  print_header(a, setup, notes.load_before);

  ServiceOnIo svc;
  std::vector<PhaseResult> phases;
  for (int round = 0; round < a.rounds; ++round) {
    for (int k = 0; k < 2; ++k) {
      const bool with = (k == 1) != (round % 2 == 1);  // without, with | with, without | …
      phases.push_back(run_phase(svc, watcher, setup, with, notes.realtime, phases.size() + 1));
    }
  }
  notes.load_after = load_average();

  const IoSummary summary = summarise(phases);
  print_summary(summary, notes);
  if (!a.json.empty())
    write_output(a.json, run_json(a, setup, notes, phases, summary).dump(1) + "\n");
  if (summary.lost != 0) {
    std::fprintf(stderr, "ncd: %lld setpoints lost: the service loop fell behind the cycle\n",
                 static_cast<long long>(summary.lost));
    return 1;
  }
  return 0;
}

}  // namespace ncd::app
