// `ncd stream` against `ncd sim-controller` over real pseudo-terminals: the program arrives
// byte-exact (the controller's SHA-256 of the blocks equals the file's), with each protocol,
// through XOFF storms and long holds, a port that vanishes and comes back, a sender killed and
// restarted from its journal, and noise from the controller.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <random>

#include "comms/sha256.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/process.hpp"
#include "tests/common/seed.hpp"

namespace ncd::test {
namespace {

class Stream : public Cli {
 protected:
  // A numbered program of `blocks` short G1 moves at a feed the controller runs quickly.
  std::string program(int blocks, double feed_mm_per_min, std::string* sha) {
    std::string text = "(ncd stream test program)\n", body;
    std::mt19937 rng(static_cast<unsigned>(blocks));
    std::uniform_real_distribution<double> d(-0.5, 0.5);
    double x = 0.0, y = 0.0;
    for (int i = 1; i <= blocks; ++i) {
      x += 0.5 + d(rng);
      y += d(rng);
      char line[96];
      std::snprintf(line, sizeof line, "N%dG1X%.3fY%.3fF%.0f", i, x, y, feed_mm_per_min);
      body += std::string(line) + "\n";
    }
    body += "M2\n";
    text += body;
    *sha = comms::sha256_hex("(ncd stream test program)\n" + body);
    return write("prog.ngc", text);
  }

  // Starts the simulated controller with extra flags; waits for its link to appear.
  std::unique_ptr<Process> controller(const std::string& flags) {
    link_ = (dir_ / "cnc").string();
    log_ = (dir_ / "cnc.json").string();
    std::vector<std::string> argv{NCD_EXE, "sim-controller", "--link", link_, "--log",
                                  log_,    "--exit-at-end"};
    std::istringstream in(flags);
    for (std::string f; in >> f;) argv.push_back(f);
    auto p =
        std::make_unique<Process>(argv, (dir_ / "cnc.out").string(), (dir_ / "cnc.err").string());
    EXPECT_TRUE(wait_for_path(link_, 5.0)) << slurp(dir_ / "cnc.err");
    return p;
  }

  nlohmann::json controller_log(Process& p, double timeout_s = 30.0) {
    const int status = p.wait(timeout_s);
    EXPECT_EQ(status, 0) << slurp(dir_ / "cnc.err");
    if (status == -2) {
      p.signal(SIGTERM);
      p.wait(5.0);
    }
    return nlohmann::json::parse(slurp(log_));
  }

  std::string link_, log_;
};

TEST_F(Stream, DripArrivesByteExact) {
  std::string sha;
  const std::string prog = program(300, 20000, &sha);
  auto cnc = controller("--baud 38400 --frame 7E2");
  const auto r = ncd("stream " + prog + " --port " + link_ + " --baud 38400 --frame 7E2 -q" +
                     " --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_EQ(log["blocks_received"], 302);  // the comment line, 300 moves, M2
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_EQ(rep["program_sha256"], sha);
  EXPECT_LE(rep["max_queued_estimate"].get<int>(), 16);
  EXPECT_FALSE(fs::exists(prog + ".journal"));
}

TEST_F(Stream, AckArrivesByteExactWithCrLf) {
  std::string sha;
  const std::string prog = program(300, 20000, &sha);
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack --eob crlf --buffer 128");
  const auto r = ncd("stream " + prog + " --port " + link_ +
                     " --baud 115200 --frame 8N1 --protocol ack --eob crlf --rx-buffer 128 -q" +
                     " --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_LE(rep["max_unacked_bytes"].get<int>(), 128);
}

TEST_F(Stream, XoffStormAndLongHoldLoseNothing) {
  std::string sha;
  const std::string prog = program(400, 20000, &sha);
  const std::uint64_t seed = ncd::test::seed();
  auto cnc = controller("--baud 38400 --frame 7E2 --buffer 256 --xoff-storm --seed " +
                        std::to_string(seed) + " --hold-after-blocks 150 --hold-s 2.5");
  const auto r =
      ncd("stream " + prog + " --port " + link_ +
          " --baud 38400 --frame 7E2 --xoff-timeout 1 -q --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("held the link"), std::string::npos) << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  EXPECT_LT(log["max_buffer_fill"].get<int>(), 256);  // never full: the sender stopped in time
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_GT(rep["xoff_count"].get<int>(), 3);
  EXPECT_EQ(rep["xoff_timeouts"], 1);
  EXPECT_GE(rep["xoff_longest_s"].get<double>(), 2.0);
}

TEST_F(Stream, PortVanishingResumesWithoutLossOrRepeat) {
  for (const std::string protocol : {"drip", "ack"}) {
    SCOPED_TRACE(protocol);
    std::string sha;
    const std::string prog = program(400, 20000, &sha);
    auto cnc = controller("--baud 38400 --frame 7E2 --protocol " + protocol +
                          " --drop-link-after-blocks 120 --down-s 1");
    const auto r =
        ncd("stream " + prog + " --port " + link_ + " --baud 38400 --frame 7E2 -q --protocol " +
            protocol + " --report " + (dir_ / "r.json").string());
    EXPECT_EQ(r.status, 0) << r.err;
    const auto log = controller_log(*cnc);
    EXPECT_EQ(log["program_sha256"], sha);
    EXPECT_EQ(log["blocks_received"], 402);
    EXPECT_EQ(log["link_drops"], 1);
    const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
    EXPECT_EQ(rep["reconnects"], 1);
  }
}

TEST_F(Stream, KilledSenderResumesFromItsJournal) {
  std::string sha;
  const std::string prog = program(500, 20000, &sha);
  auto cnc = controller("--baud 9600 --frame 7E2");
  {
    Process sender({NCD_EXE, "stream", prog, "--port", link_, "--baud", "9600", "--frame", "7E2"},
                   (dir_ / "s1.out").string(), (dir_ / "s1.err").string());
    std::this_thread::sleep_for(std::chrono::milliseconds(3000));
    ASSERT_TRUE(sender.running()) << slurp(dir_ / "s1.err");
    sender.signal(SIGKILL);
    sender.wait(5.0);
  }
  ASSERT_TRUE(fs::exists(prog + ".journal"));
  const auto again = ncd("stream " + prog + " --port " + link_ + " --baud 9600 --frame 7E2 -q");
  EXPECT_EQ(again.status, 2) << again.err;  // an unfinished transfer needs --resume or --restart
  EXPECT_NE(again.err.find("--resume"), std::string::npos) << again.err;
  const auto r = ncd("stream " + prog + " --port " + link_ +
                     " --baud 9600 --frame 7E2 --resume --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_GT(rep["first_block"].get<int>(), 50);
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_EQ(log["blocks_received"], 502);
  EXPECT_FALSE(fs::exists(prog + ".journal"));
}

TEST_F(Stream, NoiseFromTheControllerIsSurvived) {
  for (const std::string protocol : {"drip", "ack"}) {
    SCOPED_TRACE(protocol);
    std::string sha;
    const std::string prog = program(300, 20000, &sha);
    auto cnc =
        controller("--baud 38400 --frame 8N1 --noise-bytes-per-s 200 --protocol " + protocol);
    const auto r = ncd("stream " + prog + " --port " + link_ + " --baud 38400 --frame 8N1 -q" +
                       " --protocol " + protocol + " --report " + (dir_ / "r.json").string());
    EXPECT_EQ(r.status, 0) << r.err;
    const auto log = controller_log(*cnc);
    EXPECT_EQ(log["program_sha256"], sha);
    EXPECT_GT(log["noise_bytes_sent"].get<int>(), 0);
    const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
    EXPECT_GT(rep["noise_bytes"].get<int>(), 0);
  }
}

TEST_F(Stream, ControllerAlarmStopsTheTransfer) {
  std::string sha;
  const std::string prog = program(300, 20000, &sha);
  auto cnc = controller("--baud 38400 --alarm-after-blocks 40");
  const auto r = ncd("stream " + prog + " --port " + link_ + " --baud 38400 -q");
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_NE(r.out.find("NAK"), std::string::npos) << r.out;
  cnc->signal(SIGTERM);
  cnc->wait(5.0);
}

TEST_F(Stream, BadInputExitsTwoAndSendsNothing) {
  std::string sha;
  const std::string prog = program(10, 1000, &sha);
  EXPECT_EQ(ncd("stream " + prog + " --port /dev/null --frame 9X1").status, 2);
  EXPECT_EQ(ncd("stream " + prog + " --port /dev/null --baud 12345").status, 2);
  EXPECT_EQ(ncd("stream " + prog + " --port /dev/null --flow maybe").status, 2);
  EXPECT_EQ(ncd("stream " + (dir_ / "missing.ngc").string() + " --port /dev/null").status, 2);
  const std::string bad = write("bad.ngc", "N1G1X1\nN2G1X\xe9\n");
  const auto r = ncd("stream " + bad + " --port /dev/null --frame 7E2");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("bad.ngc:2"), std::string::npos) << r.err;
  // A port that does not exist fails at once (no reconnect attempts); a file is no port.
  const auto gone =
      ncd("stream " + prog + " --port " + (dir_ / "nothing").string() + " --reconnect-max 30 -q");
  EXPECT_EQ(gone.status, 2) << gone.err;
  EXPECT_NE(gone.err.find("no such file"), std::string::npos) << gone.err;
  for (const std::string& port : {std::string("/dev/null"), write("hole.json", "{}")}) {
    const auto not_tty = ncd("stream " + prog + " --port " + port + " -q");
    EXPECT_EQ(not_tty.status, 2) << port << ": " << not_tty.err;
    EXPECT_NE(not_tty.err.find("not a serial port"), std::string::npos) << not_tty.err;
  }
}

}  // namespace
}  // namespace ncd::test
