// `ncd serve` as a real process with [mqtt] against a real mosquitto: a command over MQTT holds
// the running job (seen on the control socket), a wrong token is refused as on the socket, the
// state topic follows the job, and the machine is marked offline, retained, both when it stops
// and when it is killed (the last will). Skipped when mosquitto is not installed.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "tests/api/broker.hpp"
#include "tests/api/watcher.hpp"

namespace {

using namespace std::chrono_literals;
using ncd::test::Broker;
using ncd::test::Watcher;
using nlohmann::json;
namespace fs = std::filesystem;

const std::string kServeRoot = "ncd/cell1/m1/";
const std::string kToken = "t0k-serve";

// A line client on the control socket (Unix).
class SocketClient {
 public:
  explicit SocketClient(const std::string& path) {
    fd_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    for (int i = 0; i < 400; ++i) {  // the service may still be starting
      if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return;
      std::this_thread::sleep_for(25ms);
    }
    ADD_FAILURE() << "cannot connect to " << path;
  }
  ~SocketClient() { ::close(fd_); }
  json request(json req) {
    req["token"] = kToken;
    const std::string line = req.dump() + "\n";
    if (::write(fd_, line.data(), line.size()) != static_cast<ssize_t>(line.size())) return {};
    for (;;) {
      const auto nl = buf_.find('\n');
      if (nl != std::string::npos) {
        const std::string reply = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return json::parse(reply);
      }
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 10000) <= 0) return {};
      char tmp[4096];
      const ssize_t n = ::read(fd_, tmp, sizeof tmp);
      if (n <= 0) return {};
      buf_.append(tmp, static_cast<std::size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

class ServeFleet : public ::testing::Test {
 protected:
  void SetUp() override {
    if (const std::string why = Broker::missing(); !why.empty()) GTEST_SKIP() << why;
    dir_ = fs::temp_directory_path() /
           ("ncd_fleet_serve_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    broker_ = std::make_unique<Broker>(dir_);
    ASSERT_TRUE(broker_->start()) << broker_->log();
  }
  void TearDown() override {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    broker_.reset();
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  // `ncd serve` in real time (a job long enough for commands to arrive while it moves).
  void launch() {
    socket_ = (dir_ / "ncd.sock").string();
    std::ofstream(dir_ / "serve.toml")
        << "clock = \"wall\"\nrealtime = false\ntoken = \"" << kToken << "\"\n[mqtt]\n"
        << "broker = \"" << broker_->url() << "\"\nusername = \"" << ncd::test::kMachine.name
        << "\"\npassword = \"" << ncd::test::kMachine.password << "\"\ntopic_root = \""
        << kServeRoot << "\"\nstatus_hz = 10\nreconnect_min_s = 0.1\nreconnect_max_s = 0.5\n";
    pid_ = fork();
    if (pid_ == 0) {
      const std::string err = (dir_ / "serve.err").string();
      if (!std::freopen(err.c_str(), "w", stderr)) _exit(126);
      execl(NCD_EXE, NCD_EXE, "serve", "--config", (dir_ / "serve.toml").c_str(), "--listen",
            ("unix:" + socket_).c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  // The next message on `topic` whose payload satisfies `want`, within timeout_s.
  template <class F>
  json wait_message(Watcher& w, const std::string& topic, F want, double timeout_s = 20) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      auto m = w.next(0.2);
      if (!m || m->get_topic() != topic) continue;
      const json p = json::parse(m->to_string());
      if (want(p)) return p;
    }
    return json();
  }
  json wait_state(SocketClient& c, const std::string& state) {
    json s;
    for (int i = 0; i < 500; ++i) {
      s = c.request({{"cmd", "status"}});
      if (s.value("state", "") == state) return s;
      std::this_thread::sleep_for(10ms);
    }
    ADD_FAILURE() << "the state never became " << state << ": " << s.dump();
    return s;
  }
  std::string serve_log() const {
    std::ifstream in(dir_ / "serve.err");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }

  fs::path dir_;
  std::unique_ptr<Broker> broker_;
  std::string socket_;
  pid_t pid_ = -1;
};

// The clamped cubic of the serve tests, 20 times larger: tens of seconds at the default feed.
const char* kLongCubic = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
  "points": [[0,0,0],[200,500,0],[600,-200,40],[900,600,80],[1200,0,60],[1600,400,0],
             [2000,0,0]]}})";

TEST_F(ServeFleet, ACommandOverMqttHoldsTheRunningJob) {
  Watcher ops(broker_->url(), "ops-serve", ncd::test::kOperator,
              {kServeRoot + "reply", kServeRoot + "state", kServeRoot + "online"});
  launch();
  const json online = wait_message(ops, kServeRoot + "online",
                                   [](const json& p) { return p.value("online", false); });
  ASSERT_EQ(online.value("online", false), true) << serve_log();
  std::ofstream(dir_ / "long.json") << kLongCubic;
  SocketClient c(socket_);
  json r = c.request({{"cmd", "submit"}, {"job", {{"path", (dir_ / "long.json").string()}}}});
  ASSERT_TRUE(r.value("ok", false)) << r.dump();
  ASSERT_TRUE(c.request({{"cmd", "start"}}).value("ok", false));
  wait_state(c, "running");
  EXPECT_FALSE(wait_message(ops, kServeRoot + "state", [](const json& p) {
                 return p["state"] == "running";
               }).is_null());

  ops.publish(kServeRoot + "cmd", {{"cmd", "hold"}, {"token", kToken}, {"id", "h1"}});
  const json held = wait_message(ops, kServeRoot + "reply",
                                 [](const json& p) { return p.value("id", "") == "h1"; });
  ASSERT_TRUE(held.value("ok", false)) << held.dump();
  wait_state(c, "holding");  // seen on the socket
  EXPECT_FALSE(wait_message(ops, kServeRoot + "state", [](const json& p) {
                 return p["state"] == "holding";
               }).is_null());
  // At rest under the hold, the status on MQTT carries the socket's feed limit (mm/min).
  Watcher screen(broker_->url(), "screen-serve", ncd::test::kOperator, {kServeRoot + "status"});
  const json at_rest = wait_message(screen, kServeRoot + "status", [](const json& p) {
    return p["state"] == "holding" && p["feed_mm_per_min"] == 0.0 &&
           p["feed_limit_mm_per_min"].is_number();
  });
  ASSERT_FALSE(at_rest.is_null()) << "no status at rest under the hold on " << kServeRoot
                                  << "status";
  const json socket_status = c.request({{"cmd", "status"}});
  EXPECT_EQ(at_rest["feed_limit_mm_per_min"], socket_status["feed_limit_mm_per_min"])
      << socket_status.dump();
  EXPECT_GT(at_rest["feed_limit_mm_per_min"].get<double>(), 0.0);

  // The socket's token check: a wrong token is refused and changes nothing.
  ops.publish(kServeRoot + "cmd", {{"cmd", "resume"}, {"token", "wrong"}, {"id", "r1"}});
  const json refused = wait_message(ops, kServeRoot + "reply",
                                    [](const json& p) { return p.value("id", "") == "r1"; });
  EXPECT_EQ(refused.value("ok", true), false) << refused.dump();
  EXPECT_NE(refused.value("error", "").find("token"), std::string::npos) << refused.dump();
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(c.request({{"cmd", "status"}})["state"], "holding");

  ops.publish(kServeRoot + "cmd", {{"cmd", "stop"}, {"token", kToken}, {"id", "s1"}});
  const json stopped = wait_message(ops, kServeRoot + "reply",
                                    [](const json& p) { return p.value("id", "") == "s1"; });
  EXPECT_TRUE(stopped.value("ok", false)) << stopped.dump();

  // SIGTERM: the service says it goes offline (retained), then exits 0.
  ::kill(pid_, SIGTERM);
  int status = 0;
  ::waitpid(pid_, &status, 0);
  pid_ = -1;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << serve_log();
  Watcher late(broker_->url(), "ops-late", ncd::test::kOperator, {kServeRoot + "online"});
  const auto m = late.next(10);
  ASSERT_TRUE(m);
  EXPECT_TRUE(m->is_retained());
  EXPECT_EQ(json::parse(m->to_string())["online"], false);
}

// The clamped cubic at a quarter of kLongCubic's size: a few seconds at 6000 mm/min (a path
// without F is walked as a whole job at 300 mm/min, docs/whole-program.md).
const char* kMediumCubic = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
  "points": [[0,0,0],[50,125,0],[150,-50,10],[225,150,20],[300,0,15],[400,100,0],[500,0,0]]},
  "feed_mm_per_min": 6000})";

// A real job's events reach <root>events in order, each once with consecutive "seq" from 1
// (QoS 1 may repeat one: the first of each seq is kept), and the hold sent over MQTT is a state
// event whose holder is the operator.
TEST_F(ServeFleet, AJobsEventsArriveInOrderWithConsecutiveSeq) {
  Watcher ops(broker_->url(), "ops-events", ncd::test::kOperator,
              {kServeRoot + "events", kServeRoot + "reply", kServeRoot + "online"});
  launch();
  ASSERT_EQ(wait_message(ops, kServeRoot + "online",
                         [](const json& p) { return p.value("online", false); })
                .value("online", false),
            true)
      << serve_log();
  const std::string file = (dir_ / "medium.json").string();
  std::ofstream(file) << kMediumCubic;
  SocketClient c(socket_);
  ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", file}}}}).value("ok", false));
  ASSERT_TRUE(c.request({{"cmd", "start"}}).value("ok", false));

  // Every event up to the job's end, the first of each seq. The events drive the test: the
  // "running" state event sends a hold over MQTT, the "holding" one a resume on the socket.
  std::vector<json> events;
  std::uint64_t last_seq = 0;
  bool hold_sent = false, resume_sent = false;
  json hold_reply;
  const auto end = std::chrono::steady_clock::now() + 60s;
  while (std::chrono::steady_clock::now() < end) {
    auto m = ops.next(0.2);
    if (!m) continue;
    const json e = json::parse(m->to_string());
    if (m->get_topic() == kServeRoot + "reply" && e.value("id", "") == "h1") hold_reply = e;
    if (m->get_topic() != kServeRoot + "events") continue;
    const std::uint64_t seq = e.at("seq").get<std::uint64_t>();
    if (seq <= last_seq) continue;  // a repeat (at least once)
    EXPECT_EQ(seq, last_seq + 1) << "a gap before " << e.dump();
    last_seq = seq;
    events.push_back(e);
    if (e["kind"] == "state" && e["state"] == "running" && !hold_sent) {
      ops.publish(kServeRoot + "cmd", {{"cmd", "hold"}, {"token", kToken}, {"id", "h1"}});
      hold_sent = true;
    }
    if (e["kind"] == "state" && e["state"] == "holding" && !resume_sent) {
      EXPECT_TRUE(c.request({{"cmd", "resume"}}).value("ok", false));
      resume_sent = true;
    }
    if (e["kind"] == "job" && e["text"].get<std::string>().rfind("ended", 0) == 0) break;
  }
  EXPECT_TRUE(hold_reply.is_null() || hold_reply.value("ok", false)) << hold_reply.dump();
  ASSERT_FALSE(events.empty()) << serve_log();
  EXPECT_EQ(events.front()["seq"], 1);
  // The lifecycle, in order (overrun, link or violation events may come between).
  struct Want {
    const char *kind, *state, *holder, *text;
  };
  const Want want[] = {{"state", "ready", "none", "submitted"},
                       {"job", "ready", "none", "submitted "},
                       {"state", "running", "none", "started"},
                       {"job", "running", "none", "started "},
                       {"state", "holding", "operator", "held by the operator"},
                       {"state", "running", "none", "resumed by the operator"},
                       {"state", "done", "none", ""},
                       {"job", "done", "none", "ended "}};
  std::vector<json> lifecycle;
  for (const json& e : events) {
    if (e["kind"] == "state" || e["kind"] == "job") lifecycle.push_back(e);
  }
  ASSERT_EQ(lifecycle.size(), std::size(want)) << json(lifecycle).dump(1);
  for (std::size_t i = 0; i < lifecycle.size(); ++i) {
    const json& e = lifecycle[i];
    EXPECT_EQ(e["kind"], want[i].kind) << i << ": " << e.dump();
    EXPECT_EQ(e["state"], want[i].state) << i << ": " << e.dump();
    EXPECT_EQ(e["holder"], want[i].holder) << i << ": " << e.dump();
    EXPECT_EQ(e["text"].get<std::string>().rfind(want[i].text, 0), 0u) << i << ": " << e.dump();
    EXPECT_TRUE(e.contains("job_t_s") && e.contains("service_seq")) << e.dump();
    if (i > 0) {  // the service's own order agrees with the bridge's
      EXPECT_GT(e["service_seq"].get<std::uint64_t>(),
                lifecycle[i - 1]["service_seq"].get<std::uint64_t>());
    }
  }
  // The motion time grows from the resume to the end.
  EXPECT_GT(lifecycle[6]["job_t_s"].get<double>(), lifecycle[5]["job_t_s"].get<double>());
  EXPECT_EQ(c.request({{"cmd", "status"}})["state"], "done");
}

TEST_F(ServeFleet, TheLastWillMarksAKilledServiceOffline) {
  Watcher ops(broker_->url(), "ops-will", ncd::test::kOperator, {kServeRoot + "online"});
  launch();
  ASSERT_EQ(wait_message(ops, kServeRoot + "online",
                         [](const json& p) { return p.value("online", false); })
                .value("online", false),
            true)
      << serve_log();
  ::kill(pid_, SIGKILL);  // no DISCONNECT: the broker publishes the will
  ::waitpid(pid_, nullptr, 0);
  pid_ = -1;
  const json will = wait_message(ops, kServeRoot + "online", [](const json&) { return true; });
  EXPECT_EQ(will, json({{"online", false}}));
  Watcher late(broker_->url(), "ops-late", ncd::test::kOperator, {kServeRoot + "online"});
  const auto m = late.next(10);
  ASSERT_TRUE(m);
  EXPECT_TRUE(m->is_retained());  // a screen that comes later sees it too
  EXPECT_EQ(json::parse(m->to_string())["online"], false);
}

}  // namespace

namespace {

// A "broker" that takes the TCP connection and never answers: the MQTT connection attempt stays
// pending (CONNECT sent, no CONNACK) for the client's connect timeout.
class SilentListener {
 public:
  SilentListener() {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a);
    ::listen(fd_, 8);
    socklen_t n = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n);
    port_ = ntohs(a.sin_port);
  }
  ~SilentListener() { ::close(fd_); }
  int port() const { return port_; }

 private:
  int fd_ = -1;
  int port_ = 0;
};

// The service keeps serving while the broker does not answer, and SIGTERM in the middle of a
// connection attempt still ends it cleanly (exit 0).
TEST(ServeFleetNoBroker, ServesWithoutTheBrokerAndStopsCleanlyWhileConnecting) {
  const fs::path dir =
      fs::temp_directory_path() / ("ncd_fleet_nobroker_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  SilentListener silent;
  std::ofstream(dir / "serve.toml")
      << "clock = \"simulated\"\nrealtime = false\ntoken = \"" << kToken
      << "\"\n[mqtt]\nbroker = \"tcp://127.0.0.1:" << silent.port() << "\"\ntopic_root = \""
      << kServeRoot << "\"\n";
  const std::string socket = (dir / "ncd.sock").string();
  const pid_t pid = fork();
  if (pid == 0) {
    const std::string err = (dir / "serve.err").string();
    if (!std::freopen(err.c_str(), "w", stderr)) _exit(126);
    execl(NCD_EXE, NCD_EXE, "serve", "--config", (dir / "serve.toml").c_str(), "--listen",
          ("unix:" + socket).c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  {
    SocketClient c(socket);
    EXPECT_EQ(c.request({{"cmd", "status"}}).value("state", ""), "idle");
  }
  std::this_thread::sleep_for(300ms);  // the first attempt waits for a CONNACK that never comes
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);
  std::ifstream in(dir / "serve.err");
  const std::string log((std::istreambuf_iterator<char>(in)), {});
  fs::remove_all(dir);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << log;
}

}  // namespace
