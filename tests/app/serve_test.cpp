// `ncd serve` as a real process on a real Unix socket: jobs over the socket give replay's
// setpoints, hold/resume and override keep the limits, bad requests are answered, a client
// leaving does not stop a job, SIGTERM mid-job exits 0.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "comms/sha256.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/process.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::slurp;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A line-oriented client on a Unix socket.
class Client {
 public:
  explicit Client(const std::string& path) {
    fd_ = socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    for (int i = 0; i < 200; ++i) {  // the service may still be starting
      if (connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return;
      std::this_thread::sleep_for(25ms);
    }
    ADD_FAILURE() << "cannot connect to " << path;
  }
  ~Client() { close(fd_); }
  void send_line(const std::string& line) {
    const std::string s = line + "\n";
    ASSERT_EQ(write(fd_, s.data(), s.size()), static_cast<ssize_t>(s.size()));
  }
  // The next line, or "" after 10 s.
  std::string read_line() {
    for (;;) {
      const auto nl = buf_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return line;
      }
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 10000) <= 0) return "";
      char tmp[4096];
      const ssize_t n = read(fd_, tmp, sizeof tmp);
      if (n <= 0) return "";
      buf_.append(tmp, static_cast<std::size_t>(n));
    }
  }
  json request(const json& req) {
    send_line(req.dump());
    const std::string line = read_line();
    EXPECT_FALSE(line.empty()) << "no reply to " << req.dump();
    return line.empty() ? json{{"ok", false}} : json::parse(line);
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

const char* kCubic = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
  "points": [[0,0,0],[10,25,0],[30,-10,2],[45,30,4],[60,0,3],[80,20,0],[100,0,0]]}})";

class Serve : public Cli {
 protected:
  // Starts `ncd serve` with a config of `clock` on a socket in the test folder.
  void launch(const std::string& clock, const std::string& extra = "") {
    socket_ = (dir_ / "ncd.sock").string();
    const std::string config =
        write("serve.toml", "clock = \"" + clock + "\"\nrealtime = false\n" + extra);
    pid_ = fork();
    if (pid_ == 0) {
      const std::string err = (dir_ / "serve.err").string();
      freopen(err.c_str(), "w", stderr);
      execl(NCD_EXE, NCD_EXE, "serve", "--config", config.c_str(), "--listen",
            ("unix:" + socket_).c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  // Sends SIGTERM and returns the exit status.
  int terminate() {
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  void TearDown() override {
    if (pid_ > 0) terminate();
    Cli::TearDown();
  }
  json wait_for(Client& c, const std::string& state) {
    json s;
    for (int i = 0; i < 1000; ++i) {
      s = c.request({{"cmd", "status"}});
      if (s["state"] == state) return s;
      std::this_thread::sleep_for(10ms);
    }
    ADD_FAILURE() << "state never became " << state << ": " << s.dump();
    return s;
  }

  std::string socket_;
  pid_t pid_ = -1;
};

TEST_F(Serve, JobOverTheSocketGivesReplaysSetpoints) {
  const std::string cubic = write("cubic.json", kCubic);
  ASSERT_EQ(ncd("replay " + cubic + " -q --path-only --setpoints " + (dir_ / "replay.csv").string())
                .status,
            0);
  launch("simulated");
  Client c(socket_);
  json r = c.request({{"cmd", "submit"},
                      {"job", {{"path", cubic}}},
                      {"setpoints", (dir_ / "serve.csv").string()}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  EXPECT_EQ(r["state"], "ready");
  r = c.request({{"cmd", "start"}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  const json s = wait_for(c, "done");
  EXPECT_NEAR(s["progress"].get<double>(), 1.0, 1e-12);
  EXPECT_EQ(slurp(dir_ / "serve.csv"), slurp(dir_ / "replay.csv"));
  EXPECT_EQ(terminate(), 0);
}

TEST_F(Serve, ChamferJobByParameterNames) {
  launch("simulated");
  Client c(socket_);
  json r = c.request({{"cmd", "submit"},
                      {"job",
                       {{"pipe-radius", 18},
                        {"drill-radius", 13},
                        {"ball-radius", 3},
                        {"width", 0.7},
                        {"rod-radius", 1.8},
                        {"non-knife-angle", 93}}}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  const json s = wait_for(c, "done");
  EXPECT_GT(s["setpoints"].get<int>(), 1000);
  EXPECT_NEAR(s["feed_max_mm_per_min"].get<double>(), 300.0, 1e-6);  // the chamfer's F300
}

TEST_F(Serve, InclinedChamferJobTakesTheFlagNames) {
  launch("simulated");
  Client c(socket_);
  json job = {{"pipe-radius", 18}, {"drill-radius", 13},       {"ball-radius", 3},
              {"width", 0.7},      {"drill-tilt-deg", 45},     {"drill_azimuth_deg", 0},
              {"eccentricity", 2}, {"pipe-half-angle-deg", 5}, {"pipe-thickness", 3}};
  json r = c.request({{"cmd", "submit"}, {"job", job}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  job["eccentricity"] = 6;
  job["drill-tilt-deg"] = 0;
  r = c.request({{"cmd", "submit"}, {"job", job}});
  EXPECT_FALSE(r["ok"].get<bool>());
  EXPECT_NE(r.dump().find("does not pierce"), std::string::npos) << r.dump();
}

TEST_F(Serve, HoldResumeAndOverrideKeepTheLimits) {
  const std::string cubic = write("cubic.json", kCubic);
  launch("wall");  // a 1.6 s job in real time, so that commands arrive while it moves
  Client c(socket_);
  ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}})["ok"].get<bool>());
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  std::this_thread::sleep_for(300ms);
  EXPECT_TRUE(c.request({{"cmd", "override"}, {"percent", 40}})["ok"].get<bool>());
  std::this_thread::sleep_for(200ms);
  EXPECT_TRUE(c.request({{"cmd", "hold"}})["ok"].get<bool>());
  std::this_thread::sleep_for(400ms);
  const json held = c.request({{"cmd", "status"}});
  EXPECT_EQ(held["state"], "holding");
  EXPECT_EQ(held["feed_mm_per_min"].get<double>(), 0.0);
  const auto pos = held["position"];
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(c.request({{"cmd", "status"}})["position"], pos);  // at rest on the path
  EXPECT_TRUE(c.request({{"cmd", "resume"}})["ok"].get<bool>());
  EXPECT_TRUE(c.request({{"cmd", "override"}, {"percent", 200}})["ok"].get<bool>());
  const json s = wait_for(c, "done");
  EXPECT_LE(s["accel_max"].get<double>(), 1000.0 * (1 + 1e-9));
  EXPECT_LE(s["jerk_max"].get<double>(), 20000.0 * (1 + 1e-9));
  const auto end = s["position"].get<std::vector<double>>();
  EXPECT_NEAR(end[0], 100.0, 1e-9);  // the last control point of the clamped cubic
  EXPECT_NEAR(end[1], 0.0, 1e-9);
}

TEST_F(Serve, BadRequestsAreAnsweredNotFatal) {
  launch("simulated");
  Client c(socket_);
  c.send_line("{not json");
  json r = json::parse(c.read_line());
  EXPECT_FALSE(r["ok"].get<bool>());
  EXPECT_TRUE(r.contains("error"));
  for (const json& bad : {json{{"cmd", "fly"}}, json{{"cmd", 3}}, json{{"cmd", "override"}},
                          json{{"cmd", "override"}, {"percent", "fast"}},
                          json{{"cmd", "submit"}, {"job", {{"path", "/nonexistent.json"}}}},
                          json{{"cmd", "submit"}, {"job", {{"pipe-radius", 18}}}},
                          json{{"cmd", "start"}}, json{{"cmd", "hold"}}}) {
    r = c.request(bad);
    EXPECT_FALSE(r["ok"].get<bool>()) << bad.dump();
    EXPECT_FALSE(r["error"].get<std::string>().empty()) << bad.dump();
  }
  c.send_line(std::string(100000, 'x'));
  EXPECT_FALSE(json::parse(c.read_line())["ok"].get<bool>());
  EXPECT_TRUE(c.request({{"cmd", "status"}})["ok"].get<bool>());  // still serving
}

TEST_F(Serve, ClientLeavingDoesNotStopTheJobAndSigtermExitsZero) {
  const std::string cubic = write("cubic.json", kCubic);
  launch("wall");
  {
    Client c(socket_);
    ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}})["ok"].get<bool>());
    ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  }  // the client disconnects mid-job
  std::this_thread::sleep_for(300ms);
  Client c2(socket_);
  const json s = c2.request({{"cmd", "status"}});
  EXPECT_EQ(s["state"], "running");
  EXPECT_GT(s["setpoints"].get<int>(), 10);
  EXPECT_EQ(terminate(), 0);  // SIGTERM mid-job: a clean stop on the path, exit 0
  const std::string log = slurp(dir_ / "serve.err");
  EXPECT_NE(log.find("SIGTERM"), std::string::npos) << log;
  EXPECT_NE(log.find("0 setpoints lost"), std::string::npos) << log;
}

// A machine file whose [link] names the simulated controller's port.
std::string link_machine(const std::string& device, double xoff_timeout_s) {
  return "[link]\ndevice = \"" + device +
         "\"\nbaud = 115200\nframe = \"8N1\"\nflow = \"xonxoff\"\nxoff_timeout_s = " +
         std::to_string(xoff_timeout_s) + "\n[encoder]\nmax_block_s = 0.5\n";
}

// The SHA-256 of a program file's blocks, each ended by LF (the controller's checksum).
std::string program_sha(const fs::path& file) {
  std::istringstream in(slurp(file));
  std::string all;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line != "%") all += line + "\n";
  }
  return ncd::comms::sha256_hex(all);
}

TEST_F(Serve, JobStreamsLiveToTheControllerAsReplayEncodesIt) {
  const std::string cubic = write("cubic.json", kCubic);
  const std::string link = (dir_ / "cnc").string();
  const std::string machine = write("machine.toml", link_machine(link, 5.0));
  ASSERT_EQ(ncd("replay " + cubic + " -q --path-only --machine " + machine + " --blocks " +
                (dir_ / "replay.ngc").string())
                .status,
            0);
  ncd::test::Process cnc({NCD_EXE, "sim-controller", "--link", link, "--baud", "115200", "--frame",
                          "8N1", "--log", (dir_ / "cnc.json").string(), "--exit-at-end"},
                         (dir_ / "cnc.out").string(), (dir_ / "cnc.err").string());
  ASSERT_TRUE(ncd::test::wait_for_path(link, 5.0));
  launch("simulated", "machine = \"" + machine + "\"\n");
  Client c(socket_);
  ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}})["ok"].get<bool>());
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  const json s = wait_for(c, "done");
  const std::string sha = program_sha(dir_ / "replay.ngc");
  ASSERT_TRUE(s["stream"].is_object()) << s.dump();
  EXPECT_TRUE(s["stream"]["completed"].get<bool>()) << s.dump();
  EXPECT_EQ(s["stream"]["program_sha256"], sha);
  EXPECT_EQ(cnc.wait(30.0), 0) << slurp(dir_ / "cnc.err");
  const json log = json::parse(slurp(dir_ / "cnc.json"));
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_TRUE(log["alarms"].empty());
}

TEST_F(Serve, LinkHoldHoldsTheMotionAndResumes) {
  const std::string cubic = write("cubic.json", kCubic);
  const std::string link = (dir_ / "cnc").string();
  const std::string machine = write("machine.toml", link_machine(link, 0.3));
  ncd::test::Process cnc({NCD_EXE, "sim-controller", "--link", link, "--baud", "115200", "--frame",
                          "8N1", "--log", (dir_ / "cnc.json").string(), "--exit-at-end",
                          "--hold-after-blocks", "4", "--hold-s", "1.5"},
                         (dir_ / "cnc.out").string(), (dir_ / "cnc.err").string());
  ASSERT_TRUE(ncd::test::wait_for_path(link, 5.0));
  launch("wall", "machine = \"" + machine + "\"\n");
  Client c(socket_);
  ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}})["ok"].get<bool>());
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  const json held = wait_for(c, "holding");
  EXPECT_TRUE(held["stream"]["held_by_link"].get<bool>()) << held.dump();
  const json s = wait_for(c, "done");
  EXPECT_TRUE(s["stream"]["completed"].get<bool>()) << s.dump();
  EXPECT_GE(s["stream"]["xoff_timeouts"].get<int>(), 1);
  EXPECT_LE(s["accel_max"].get<double>(), 1000.0 * (1 + 1e-9));
  EXPECT_LE(s["jerk_max"].get<double>(), 20000.0 * (1 + 1e-9));
  EXPECT_EQ(cnc.wait(30.0), 0);
  const json log = json::parse(slurp(dir_ / "cnc.json"));
  EXPECT_EQ(log["program_sha256"], s["stream"]["program_sha256"]);
  EXPECT_TRUE(log["alarms"].empty());
  const std::string err = slurp(dir_ / "serve.err");
  EXPECT_NE(err.find("the link holds"), std::string::npos) << err;
  EXPECT_NE(err.find("resuming the motion"), std::string::npos) << err;
}

}  // namespace
