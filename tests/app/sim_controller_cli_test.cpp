// `ncd sim-controller` as a real process: the line it prints, SIGTERM writes the log, with
// --exit-at-end it leaves on its own after the program, bad flags exit 2 and leave nothing.
// The sender is a plain open/write on the linked path.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "link/sha256.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/process.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::Process;
using ncd::test::slurp;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

class SimControllerCli : public Cli {
 protected:
  // Starts `ncd sim-controller --link DIR/cnc --log DIR/log.json ARGS...` and waits for the link.
  std::unique_ptr<Process> start(std::vector<std::string> args) {
    std::vector<std::string> argv = {NCD_EXE, "sim-controller", "--link",
                                     link(),  "--log",          (dir_ / "log.json").string()};
    argv.insert(argv.end(), args.begin(), args.end());
    auto p = std::make_unique<Process>(argv, (dir_ / "out").string(), (dir_ / "err").string());
    EXPECT_TRUE(ncd::test::wait_for_path(link(), 5.0)) << slurp(dir_ / "err");
    return p;
  }
  std::string link() const { return (dir_ / "cnc").string(); }

  // Opens the link raw and writes `text` at once (it must fit the controller's buffer).
  void send(const std::string& text) {
    const int fd = ::open(link().c_str(), O_RDWR | O_NOCTTY);
    ASSERT_GE(fd, 0);
    termios t{};
    ::tcgetattr(fd, &t);
    ::cfmakeraw(&t);
    ::tcsetattr(fd, TCSANOW, &t);
    ASSERT_EQ(::write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
    std::this_thread::sleep_for(100ms);  // on the wire before the port closes
    ::close(fd);
  }
};

TEST_F(SimControllerCli, PrintsTheLinkAndWritesTheLogOnSigterm) {
  auto p = start({"--baud", "115200", "--frame", "8N1", "--seed", "42"});
  const std::string blocks = "N1 G1 X1 F6000\nN2 G1 Y1\nN3 G0 Z5\n";
  send(blocks);
  // Primed after 0.5 s without a character, then executed in about 80 ms, then dry for longer
  // than the grace: 1.5 s leaves a loaded machine about 0.9 s (the log is written only at exit).
  std::this_thread::sleep_for(1500ms);
  p->signal(SIGTERM);
  ASSERT_EQ(p->wait(10.0), 0) << slurp(dir_ / "err");
  const std::string out = slurp(dir_ / "out");
  EXPECT_NE(out.find(link() + " -> /dev/pts/"), std::string::npos) << out;
  EXPECT_NE(out.find("115200 8N1 xonxoff drip LF"), std::string::npos) << out;
  EXPECT_NE(out.find("XOFF at 192, XON at 96"), std::string::npos) << out;
  EXPECT_NE(out.find("seed 42"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(fs::symlink_status(link())));  // removed on exit

  const json log = json::parse(slurp(dir_ / "log.json"));
  for (const char* key :
       {"blocks_received", "program_sha256", "underruns", "underrun_events", "dwell_s", "alarms",
        "bytes_received", "bytes_per_s", "link_use", "max_buffer_fill", "buffer_bytes",
        "duplicates_discarded", "link_drops", "xoff_sent", "noise_bytes_sent",
        "program_end_received", "settings", "moves"}) {
    EXPECT_TRUE(log.contains(key)) << key;
  }
  EXPECT_EQ(log["stop_reason"], "stop_requested");
  EXPECT_EQ(log["blocks_received"], 3);
  EXPECT_EQ(log["program_sha256"], ncd::comms::sha256_hex(blocks));
  EXPECT_EQ(log["bytes_received"], blocks.size());
  EXPECT_EQ(log["settings"]["baud"], 115200);
  EXPECT_EQ(log["settings"]["seed"], 42);
  EXPECT_FALSE(log["program_end_received"].get<bool>());
  ASSERT_EQ(log["moves"].size(), 3U);
  EXPECT_EQ(log["moves"][2]["p"], json::array({1.0, 1.0, 5.0}));
  EXPECT_EQ(log["moves"][2]["feed_mm_per_min"], 5000.0);  // G0 at the rapid rate
  EXPECT_EQ(log["underruns"], 1);  // waiting for more of a program that never ended
  EXPECT_TRUE(log["alarms"].empty());
}

TEST_F(SimControllerCli, ExitAtEndLeavesAfterTheProgram) {
  auto p = start({"--exit-at-end", "--protocol", "drip", "--eob", "crlf"});
  send("%\r\nN10 G1 X2 F12000\r\nN20 M30\r\n%\r\n");
  ASSERT_EQ(p->wait(10.0), 0) << slurp(dir_ / "err");
  const json log = json::parse(slurp(dir_ / "log.json"));
  EXPECT_EQ(log["stop_reason"], "program_end");
  EXPECT_TRUE(log["program_end_executed"].get<bool>());
  EXPECT_EQ(log["program_sha256"], ncd::comms::sha256_hex("N10 G1 X2 F12000\nN20 M30\n"));
  EXPECT_EQ(log["framing_lines"], 2);
  EXPECT_FALSE(fs::exists(fs::symlink_status(link())));
}

TEST_F(SimControllerCli, BadFlagsExitTwoAndLeaveNothing) {
  write("file", "not a link");
  const std::string l = " --link " + link();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "--link"},
      {l + " --buffer 10", "--buffer 10"},
      {l + " --frame 9N1", "9N1"},
      {l + " --flow hw", "hw"},
      {l + " --protocol zmodem", "zmodem"},
      {l + " --baud 12345", "12345"},
      {l + " --xoff-at 300", "--xoff-at 300"},
      {l + " --xon-at 200", "--xon-at 200"},
      {l + " --planner-blocks 0", "--planner-blocks 0"},
      {l + " --xoff-storm --flow none", "--xoff-storm"},
      {l + " --hold-after-blocks 3 --protocol ack", "--hold-after-blocks"},
      {l + " --noise-bytes-per-s -1", "--noise-bytes-per-s"},
      {l + " --down-s -1", "--down-s"},
      {l + " --seed -5", "--seed"},
      {l + " --protocol ack --status-mask 4", "--status-mask 4"},
      {l + " --protocol ack --accel 0", "--accel 0"},
      {l + " --restart-after-blocks 3", "--restart-after-blocks"},  // drip: no banner to lose
      {l + " --log " + (dir_ / "missing" / "log.json").string(), "missing"},
      {" --link " + (dir_ / "file").string(), "symbolic link"},
      {" --link " + (dir_ / "missing" / "cnc").string(), "missing"},
  };
  for (const auto& [args, mention] : cases) {
    const auto r = ncd("sim-controller" + args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(mention), std::string::npos) << args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(fs::symlink_status(link()))) << args;
  }
  EXPECT_EQ(slurp(dir_ / "file"), "not a link");
}

}  // namespace
