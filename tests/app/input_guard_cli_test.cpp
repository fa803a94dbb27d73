// Issue 11's parser reproducers, byte for byte, against the real `ncd` and `ncd serve`: each is
// exit 2 (or an error reply) with a message naming the file, the key or the value, and the
// service stays up. docs/input-ranges.md states the rules these check.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "tests/app/cli_fixture.hpp"
#include "tests/common/char_device.hpp"
#include "tests/common/test_paths.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

class Guard : public Cli {
 protected:
  // Exit 2, every part in the message, and no output file written.
  void expect_refused(const CmdResult& r, const std::vector<std::string>& parts,
                      const std::string& what) {
    EXPECT_EQ(r.status, 2) << what << "\n" << r.err;
    for (const std::string& p : parts) {
      EXPECT_NE(r.err.find(p), std::string::npos) << what << ": '" << p << "'\n" << r.err;
    }
    EXPECT_EQ(r.err.find("internal error"), std::string::npos) << what << "\n" << r.err;
    EXPECT_FALSE(fs::exists(dir_ / "out.csv")) << what;
  }
  CmdResult replay_with(const std::string& machine_text) {
    const std::string path = write("cubic.json", ncd::test::kCubicJson);
    const std::string machine = write("m.toml", machine_text);
    return ncd("replay " + path + " -q --machine " + machine + " --setpoints " +
               (dir_ / "out.csv").string());
  }
};

TEST_F(Guard, MachineFileWithInvalidUtf8OrNulIsRefusedWithItsPosition) {
  expect_refused(replay_with("[link]\ndevice = '\xFF'\n"),
                 {"m.toml: line 2, column 11 (byte offset 17)", "0xFF is not valid UTF-8"},
                 "0xFF in a literal string");
  expect_refused(replay_with("'\xBE"), {"line 1, column 2 (byte offset 1)", "0xBE"}, "'0xBE");
  expect_refused(replay_with(std::string("period_s = 0.004\0\n", 18)),
                 {"line 1, column 17 (byte offset 16)", "a NUL byte"}, "NUL");
}

TEST_F(Guard, DeepNestingInTheMachineFileIsRefusedBeforeParsing) {
  std::string table = "a = ";
  for (int i = 0; i < 100000; ++i) table += "{b=";
  expect_refused(replay_with("a = " + std::string(100000, '[')),
                 {"byte offset 68", "deeper than 64"}, "a = [[[[");
  expect_refused(replay_with(table), {"byte offset 196", "deeper than 64"}, "a = {b={b=");
}

TEST_F(Guard, MachineValuesOutsideTheirRangeNameValueRangeAndWayOut) {
  struct Case {
    std::string text;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases{
      {"max_feed_mm_per_min = 1e12\n",
       {"max_feed_mm_per_min = 1000000000000", "[1, 120000] mm/min", "leave the key out"}},
      {"max_accel_mm_per_s2 = 1e-6\n", {"max_accel_mm_per_s2 = 1e-06", "[10, 100000]"}},
      {"max_jerk_mm_per_s3 = 1e-300\n", {"max_jerk_mm_per_s3 = 1e-300", "[100, 10000000]"}},
      {"max_jerk_mm_per_s3 = 1e9\n", {"max_jerk_mm_per_s3 = 1000000000", "[100, 10000000]"}},
      {"max_jerk_mm_per_s3 = 1e300\n", {"max_jerk_mm_per_s3 = 1e+300"}},
      {"max_feed_mm_per_min = inf\n", {"max_feed_mm_per_min = inf"}},
      {"chord_tolerance_mm = 1e-9\n", {"chord_tolerance_mm = 1e-09", "[0.0001, 1] mm"}},
      {"period_s = 0.5\n", {"period_s = 0.5", "[0.0001, 0.1] s"}},
      {"[cutting]\nspindle_rpm = 1e7\n", {"cutting.spindle_rpm = 10000000", "[1, 200000] rpm"}},
      {"[cutting]\nball_radius_mm = 1000\n", {"cutting.ball_radius_mm = 1000"}},
      {"[cutting]\nteeth = 9223372036854775807\n",
       {"cutting.teeth = 9223372036854775807 is out of range", "from 1 to 1000"}},
      {"[link]\nxoff_timeout_s = 1e9\n", {"link.xoff_timeout_s = 1000000000"}},
      {"[encoder]\nmax_block_s = 1e9\n", {"encoder.max_block_s = 1000000000"}},
  };
  for (const Case& c : cases) {
    std::vector<std::string> says = c.says;
    says.push_back("m.toml");
    if (c.text.find("teeth") == std::string::npos) says.push_back("docs/input-ranges.md");
    expect_refused(replay_with(c.text), says, c.text);
  }
  // The example file's values (the defaults) are all inside.
  const CmdResult ok = ncd("replay " + write("c.json", ncd::test::kCubicJson) + " -q --machine " +
                           std::string(NCD_SOURCE_DIR) + "/config/machine.example.toml");
  EXPECT_EQ(ok.status, 0) << ok.err;
}

TEST_F(Guard, EveryInputFileMustBeARegularFile) {
  const std::string fifo = (dir_ / "fifo").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::string cubic = write("cubic.json", ncd::test::kCubicJson);
  const std::string dir = dir_.string();
  const std::string csv = " --setpoints " + (dir_ / "out.csv").string();
  const std::string device = ncd::test::character_device();
  struct Case {
    std::string args, says;
  };
  // A FIFO without a writer: before the fix, each of these blocked in open() forever.
  for (const Case& c : std::vector<Case>{
           {"replay " + cubic + " --machine " + dir + csv, dir + " (machine file, --machine) is "
                                                                 "a directory"},
           {"replay " + cubic + " --machine " + fifo + csv, "is a FIFO (named pipe)"},
           {"replay " + dir + csv, dir + " (path file) is a directory"},
           {"replay " + fifo + csv, fifo + " (path file) is a FIFO"},
           {"replay " + device + csv, device + " (path file) is a character device"},
           {"serve --config " + dir, "(service config, --config) is a directory"},
           {"serve --config " + fifo, "(service config, --config) is a FIFO"},
       }) {
    expect_refused(ncd(c.args), {c.says, "not a regular file"}, c.args);
  }
}

TEST_F(Guard, PathFilesRefuseUnrepresentableNumbersDeepNestingAndZeroLength) {
  struct Case {
    std::string text;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases{
      {R"({"nurbs":1e400})", {"p.json: \"nurbs\" is out of range", "1e400"}},
      {R"({"polyline":{"points":[[0,0,0],[1e999,0,0]]}})",
       {"\"polyline.points[1][0]\" is out of range"}},
      {R"({"polyline":{"points":)" + std::string(100000, '['),
       {"p.json: line 1, column 85 (byte offset 84)", "nesting deeper than 64"}},
      {R"({"nurbs":{"degree":2,"knots":[0,0,0,1,1,1],"points":[[1,2,3],[1,2,3],[1,2,3]]}})",
       {"\"nurbs.points\" are all the same point", "zero length"}},
      {R"({"nurbs":{"degree":4.9,"knots":[],"points":[]}})",
       {"\"nurbs.degree\" = 4.9 is not a whole number", "from 1 to 7"}},
      {R"({"polyline":{"points":[[0,0,0],[1,0,0]]},"feed_mm_per_min":0.0001})",
       {"\"feed_mm_per_min\" = 0.0001 is outside", "[0.1, 120000] mm/min"}},
      {R"({"polyline":{"points":[[0,0,0],[1e9,0,0]]}})",
       {"\"polyline.points[1][0]\" = 1000000000.0 is outside", "mm"}},
  };
  for (const Case& c : cases) {
    const std::string p = write("p.json", c.text);
    expect_refused(ncd("replay " + p + " -q --setpoints " + (dir_ / "out.csv").string()), c.says,
                   c.text.substr(0, 80));
  }
}

TEST_F(Guard, NumberReadersUseTheDecimalGrammar) {
  const std::string robot = "robot --cylinder-radius 50 --hole-radius 20 -q -o " +
                            (dir_ / "out.csv").string() + " --touch-points ";
  const std::string touches = write("t.txt", "0x1p5 0 0 32 0 0\n");
  expect_refused(ncd(robot + touches), {"t.txt:1: '0x1p5' is not a number"}, "hex float");
  const std::string tiny = write("tiny.txt", "1e-310 0 0 0 0 0\n");
  expect_refused(ncd(robot + tiny),
                 {"tiny.txt:1: '1e-310' is too small", "write 0 if zero is meant"}, "1e-310");
  const std::string frame = write("frame.txt", "0 0 0\n100 0 0\n0 100 0\n");
  const std::string points = write("pts.txt", "dp1 1 2 3\ndp2 +-10 2 3\n");
  expect_refused(ncd("teach " + points + " --frame-points " + frame +
                     " --tool-diameter 10 --depth 0.2 --feed 300 --spindle 2000 -o " +
                     (dir_ / "out.csv").string()),
                 {"pts.txt:2", "'+-10' (x) is not a number"}, "+-10");
}

// ---------------------------------------------------------------------------- the service

class GuardServe : public Guard {
 protected:
  void SetUp() override {
    Guard::SetUp();
    socket_ = (dir_ / "ncd.sock").string();
    const std::string config = write("serve.toml", "clock = \"simulated\"\nrealtime = false\n");
    pid_ = fork();
    if (pid_ == 0) {
      freopen((dir_ / "serve.err").c_str(), "w", stderr);
      execl(NCD_EXE, NCD_EXE, "serve", "--config", config.c_str(), "--listen",
            ("unix:" + socket_).c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    fd_ = socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", socket_.c_str());
    for (int i = 0; i < 400; ++i) {  // the service may still be starting
      if (connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return;
      std::this_thread::sleep_for(25ms);
    }
    FAIL() << "cannot connect to " << socket_;
  }
  void TearDown() override {
    close(fd_);
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the service did not exit 0";
    Guard::TearDown();
  }
  // One request line, its reply; "" when none came within 20 s (a blocked I/O thread).
  std::string ask(const std::string& line) {
    const std::string s = line + "\n";
    EXPECT_EQ(::write(fd_, s.data(), s.size()), static_cast<ssize_t>(s.size()));
    for (;;) {
      if (const auto nl = buf_.find('\n'); nl != std::string::npos) {
        std::string reply = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return reply;
      }
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 20000) <= 0) return "";
      char tmp[4096];
      const ssize_t n = read(fd_, tmp, sizeof tmp);
      if (n <= 0) return "";
      buf_.append(tmp, static_cast<std::size_t>(n));
    }
  }
  void expect_error_reply(const std::string& line, const std::vector<std::string>& says) {
    const std::string reply = ask(line);
    ASSERT_FALSE(reply.empty()) << "no reply to " << line.substr(0, 100);
    const json r = json::parse(reply);
    EXPECT_FALSE(r["ok"].get<bool>()) << reply;
    const std::string error = r.value("error", "");
    for (const std::string& s : says)
      EXPECT_NE(error.find(s), std::string::npos) << s << "\n" << error;
    EXPECT_EQ(error.find("internal error"), std::string::npos) << error;
  }

  std::string socket_, buf_;
  pid_t pid_ = -1;
  int fd_ = -1;
};

TEST_F(GuardServe, AFifoJobIsRefusedAndTheServiceKeepsAnswering) {
  const std::string fifo = (dir_ / "job.fifo").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  // Before the fix the open() of the FIFO blocked the I/O thread: no reply, ever.
  expect_error_reply(json{{"cmd", "submit"}, {"job", {{"path", fifo}}}}.dump(),
                     {fifo + " (path file) is a FIFO (named pipe), not a regular file"});
  expect_error_reply(json{{"cmd", "submit"}, {"job", {{"path", dir_.string()}}}}.dump(),
                     {"is a directory"});
  const json status = json::parse(ask(R"({"cmd":"status"})"));
  EXPECT_TRUE(status["ok"].get<bool>());
  EXPECT_EQ(status["state"], "idle");
}

TEST_F(GuardServe, IntegersMustBeWholeAndInRangeNumbersRepresentable) {
  const std::string chamfer =
      R"({"cmd":"submit","job":{"pipe_radius":30,"drill_radius":10,"ball_radius":3,"width":1,)";
  expect_error_reply(chamfer + R"("initial_segments":3e9}})",
                     {"\"initial_segments\" = 3000000000 is out of range", "from 4 to 100000"});
  expect_error_reply(chamfer + R"("initial_segments":4.9}})",
                     {"\"initial_segments\" = 4.9 is not a whole number", "from 4 to 100000"});
  expect_error_reply(R"({"cmd":"override","percent":1e400})", {"\"percent\" is out of range"});
  expect_error_reply(R"({"cmd":"subscribe","hz":1e-10})",
                     {"\"hz\" = 1e-10 is out of range", "at least 0.1"});
  expect_error_reply(R"({"cmd":)" + std::string(60000, '['), {"nesting deeper than 64"});
  expect_error_reply("{\"cmd\":\"\xFF\"}", {"not valid JSON"});
  EXPECT_TRUE(json::parse(ask(R"({"cmd":"status"})"))["ok"].get<bool>());
}

}  // namespace
