// `ncd serve` against everything that crashed or hung it (issue 11), thousands of random and
// mutated request lines (the seed is printed), the job states (stopped, the position before the
// first period, time_left_s while held) and the chamfer rules of a job. The service must answer
// every line and stay up.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "tests/app/serve_fixture.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"

namespace {

using ncd::test::slurp;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

using HardeningClient = ncd::test::ServeClient;

const char* kCubic = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
  "points": [[0,0,0],[10,25,0],[30,-10,2],[45,30,4],[60,0,3],[80,20,0],[100,0,0]]},
  "feed_mm_per_min": 3000})";

class ServeHardening : public ncd::test::ServeFixture {};

TEST_F(ServeHardening, EveryRequestShapeThatCrashedOrHungItIsAnErrorReply) {
  const std::string cubic = write("cubic.json", kCubic);
  const std::string file_port = write("hole.json", "{}");
  launch("simulated");
  HardeningClient c(socket_);
  // Ports that are no serial port: refused at submit, so `start` can never abort the service.
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}, {"port", "/dev/full"}}),
               "not a serial port", "/dev/full");
  EXPECT_FALSE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}, {"port", file_port}}),
               "not a serial port", "a regular file");
  expect_error(c.request({{"cmd", "submit"},
                          {"job", {{"path", cubic}}},
                          {"port", (dir_ / "no-such-tty").string()}}),
               "no such file", "a missing port");
  // Rates and keys.
  expect_error(c.request_line(R"({"cmd":"subscribe","hz":1e-10})"), "at least 0.1", "hz");
  expect_error(c.request({{"cmd", "status"}, {"verbose", true}}), "unknown key \"verbose\"",
               "status");
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}, {"prot", "/dev/x"}}),
               "unknown key \"prot\"", "submit");
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}, {"speed", 3}}}}),
               "unknown key", "job key");
  expect_error(c.request({{"cmd", "hold"}, {"now", 1}}), "unknown key", "hold");
  // Integers that are no integers, or out of range.
  for (const char* segments : {"3e9", "4.9", "-1", "0"}) {
    expect_error(c.request_line(std::string(R"({"cmd":"submit","job":{"pipe_radius":30,)") +
                                R"("drill_radius":10,"ball_radius":3,"width":1,)" +
                                R"("initial_segments":)" + segments + "}}"),
                 "initial_segments", segments);
  }
  expect_error(
      c.request({{"cmd", "submit"}, {"job", {{"path", cubic}, {"allow_interference", "yes"}}}}),
      "allow_interference", "allow_interference");
  // Still up, and still runs a job to the end.
  EXPECT_TRUE(alive());
  ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}})["ok"].get<bool>());
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  wait_for(c, "done");
  EXPECT_TRUE(alive());
}

// Random lines: valid requests, mutated byte by byte or with hostile values put in. Each gets
// exactly one reply; the service is up at the end.
TEST_F(ServeHardening, ThousandsOfRandomAndMutatedLinesAreAllAnswered) {
  const std::uint64_t seed = ncd::test::seed();
  std::mt19937_64 rng(seed);
  const std::string cubic = write("cubic.json", kCubic);
  launch("simulated");
  HardeningClient c(socket_);
  const std::vector<json> valid = {
      {{"cmd", "status"}},
      {{"cmd", "start"}},
      {{"cmd", "hold"}},
      {{"cmd", "resume"}},
      {{"cmd", "stop"}},
      {{"cmd", "override"}, {"percent", 50}},
      {{"cmd", "submit"}, {"job", {{"path", cubic}}}},
      {{"cmd", "submit"}, {"job", {{"path", cubic}}}, {"port", ""}},
      {{"cmd", "submit"},
       {"job",
        {{"pipe_radius", 18},
         {"drill_radius", 13},
         {"ball_radius", 3},
         {"width", 0.7},
         {"tolerance", 0.01}}}},
  };
  const std::vector<std::string> hostile = {"-1",
                                            "0",
                                            "1e400",
                                            "-1e400",
                                            "1e-300",
                                            "3e9",
                                            "4.9",
                                            "null",
                                            "true",
                                            "[]",
                                            "{}",
                                            "\"\"",
                                            "\"/dev/full\"",
                                            "[[[[[[1]]]]]]",
                                            "\"\\u0000\"",
                                            "1e308",
                                            "-0",
                                            "\"x\"",
                                            "{\"a\":{\"b\":1}}"};
  const std::string alphabet = "{}[]\":,0123456789.-+eE abcdefghijklmnopqrstuvwxyz\\\x01\xff";
  constexpr int kLines = 3000;
  int answered = 0, skipped = 0;
  for (int i = 0; i < kLines; ++i) {
    json base = valid[rng() % valid.size()];
    std::string line;
    switch (rng() % 3) {
      case 0: {  // a hostile value under an existing or a new key
        const std::vector<std::string> keys = {"cmd", "job", "port", "percent", "hz", "extra"};
        const std::string key = keys[rng() % keys.size()];
        std::string text = base.dump();
        text.insert(1, "\"" + key + "\":" + hostile[rng() % hostile.size()] + ",");
        line = text;
        break;
      }
      case 1: {  // byte mutations
        line = base.dump();
        const int edits = 1 + static_cast<int>(rng() % 4);
        for (int e = 0; e < edits && !line.empty(); ++e) {
          const std::size_t at = rng() % line.size();
          const char ch = alphabet[rng() % alphabet.size()];
          switch (rng() % 3) {
            case 0:
              line[at] = ch;
              break;
            case 1:
              line.insert(at, 1, ch);
              break;
            default:
              line.erase(at, 1);
          }
        }
        break;
      }
      default: {  // random bytes
        const std::size_t n = 1 + rng() % 60;
        for (std::size_t k = 0; k < n; ++k) line += alphabet[rng() % alphabet.size()];
      }
    }
    for (char& ch : line) {
      if (ch == '\n' || ch == '\r') ch = ' ';
    }
    // Lines the protocol answers otherwise: blank ones get no reply, and a valid subscribe
    // starts a status stream (its rate bounds are tested above).
    if (line.find_first_not_of(" \t") == std::string::npos) {
      ++skipped;
      continue;
    }
    try {
      const json parsed = json::parse(line);
      if (parsed.is_object() && parsed.value("cmd", json()) == "subscribe") {
        ++skipped;
        continue;
      }
    } catch (const json::exception&) {
    }
    ASSERT_TRUE(c.send_line(line)) << "seed " << seed << ", line " << i << ": " << line;
    const std::string reply = c.read_line();
    ASSERT_FALSE(reply.empty()) << "seed " << seed << ", no reply to line " << i << ": " << line;
    json r;
    ASSERT_NO_THROW(r = json::parse(reply)) << reply;
    ASSERT_TRUE(r.contains("ok")) << reply;
    if (!r["ok"].get<bool>()) {
      EXPECT_EQ(r.value("error", "").find("internal error"), std::string::npos)
          << "seed " << seed << ", line " << i << ": " << line << "\n"
          << reply;
    }
    ++answered;
  }
  std::cout << "[ lines    ] " << answered << " answered, " << skipped << " skipped\n";
  EXPECT_GT(answered, kLines * 9 / 10);
  EXPECT_TRUE(alive()) << "seed " << seed;
  EXPECT_TRUE(c.request({{"cmd", "status"}})["ok"].get<bool>()) << "seed " << seed;
}

TEST_F(ServeHardening, StopEndsTheJobAsStoppedWithWhyAndWhere) {
  const std::string cubic = write("cubic.json", kCubic);
  launch("wall");  // a 3 s job in real time, so that the stop arrives while it moves
  HardeningClient c(socket_);
  ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}})["ok"].get<bool>());
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  json s;
  for (int i = 0; i < 500; ++i) {
    s = c.request({{"cmd", "status"}});
    if (s["setpoints"].get<int>() > 50) break;
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_EQ(s["state"], "running") << s.dump();
  ASSERT_TRUE(c.request({{"cmd", "stop"}})["ok"].get<bool>());
  s = wait_for(c, "stopped");
  ASSERT_TRUE(s["stopped"].is_object()) << s.dump();
  EXPECT_EQ(s["stopped"]["why"], "stop requested by a client");
  const double s_mm = s["stopped"]["s_mm"].get<double>();
  EXPECT_GT(s_mm, 0.0);
  EXPECT_LT(s_mm, s["stopped"]["length_mm"].get<double>());
  EXPECT_LT(s["progress"].get<double>(), 1.0);
  // Where it stopped is where the machine is: the status position, at rest.
  EXPECT_EQ(s["stopped"]["position"], s["position"]) << s.dump();
  EXPECT_EQ(s["feed_mm_per_min"].get<double>(), 0.0);
  EXPECT_EQ(s["time_left_s"].get<double>(), 0.0);
  // A new job may follow.
  EXPECT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", cubic}}}})["ok"].get<bool>());
}

TEST_F(ServeHardening, PositionBeforeTheFirstPeriodIsThePathsStartAndTimeLeftHoldsStill) {
  // A path that starts far from the origin.
  const std::string line =
      write("line.json",
            R"({"polyline":{"points":[[10,20,5],[60,20,5],[60,70,5]]},"feed_mm_per_min":2000})");
  launch("wall");
  HardeningClient c(socket_);
  ASSERT_TRUE(c.request({{"cmd", "submit"}, {"job", {{"path", line}}}})["ok"].get<bool>());
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  json s = c.request({{"cmd", "status"}});
  const auto p = s["position"].get<std::vector<double>>();
  // Never [0,0,0]: the whole job's planned motion starts over the path's start at its clearance
  // plane, 2 R_B + 5 mm above the path's highest point (docs/whole-program.md; the default R_B
  // is 5 mm), and goes straight down to it. The job runs on the wall clock, so how far down the
  // status finds it depends on how soon this client is scheduled (0.01 mm after 20 ms, 0.4 mm
  // after 50 ms): on the approach, between the clearance plane and the path.
  EXPECT_NEAR(p[0], 10.0, 1e-9) << s.dump();
  EXPECT_NEAR(p[1], 20.0, 1e-9) << s.dump();
  EXPECT_LE(p[2], 5.0 + 2.0 * 5.0 + 5.0 + 1e-9) << s.dump();
  EXPECT_GE(p[2], 5.0 - 1e-9) << s.dump();
  // Let it move, hold, and watch time_left_s while held: it must not grow.
  for (int i = 0; i < 500; ++i) {
    s = c.request({{"cmd", "status"}});
    if (!s["time_left_s"].is_null() && s["progress"].get<double>() > 0.1) break;
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_EQ(s["state"], "running") << s.dump();
  ASSERT_TRUE(c.request({{"cmd", "hold"}})["ok"].get<bool>());
  const json first = c.request({{"cmd", "status"}});
  ASSERT_TRUE(first["time_left_s"].is_number()) << first.dump();
  double last = first["time_left_s"].get<double>();
  for (int i = 0; i < 8; ++i) {
    std::this_thread::sleep_for(100ms);
    const json h = c.request({{"cmd", "status"}});
    ASSERT_EQ(h["state"], "holding");
    EXPECT_LE(h["time_left_s"].get<double>(), last) << h.dump();
    last = h["time_left_s"].get<double>();
  }
  ASSERT_TRUE(c.request({{"cmd", "resume"}})["ok"].get<bool>());
  wait_for(c, "done");
}

TEST_F(ServeHardening, ChamferJobsRefuseFailedChecksAndAnotherTool) {
  // A chamfer whose checks fail (a 12 mm ball in a 13 mm hole), and a good one for a 3 mm ball.
  const std::string big = (dir_ / "big.json").string();
  ASSERT_EQ(
      ncd("chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 12 --width 0.7 -q -o " + big)
          .status,
      0);
  const std::string exp3 = (dir_ / "exp3.json").string();
  ASSERT_EQ(ncd("chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 "
                "--tolerance 0.01 -q -o " +
                exp3)
                .status,
            0);
  const std::string machine5 = write("m5.toml", "[cutting]\nball_radius_mm = 5.0\n");
  launch("simulated", "machine = \"" + machine5 + "\"\n");
  HardeningClient c(socket_);
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", big}}}}), "interference",
               "big.json");
  const auto chamfer_job = [](double ball_radius_mm) {
    return json{{"cmd", "submit"},
                {"job",
                 {{"pipe_radius", 18},
                  {"drill_radius", 13},
                  {"ball_radius", ball_radius_mm},
                  {"width", 0.7}}}};
  };
  expect_error(c.request(chamfer_job(12)), "interference", "a chamfer job for a 12 mm ball");
  // The tool: the job's 3 mm against the machine's 5 mm, both named.
  const json mismatch = c.request({{"cmd", "submit"}, {"job", {{"path", exp3}}}});
  expect_error(mismatch, "ball radius of 3 mm", "exp3.json on a 5 mm machine");
  EXPECT_NE(mismatch.value("error", "").find("ball_radius_mm = 5 mm"), std::string::npos)
      << mismatch.dump();
  expect_error(c.request(chamfer_job(3)), "ball radius of 3 mm",
               "a 3 mm chamfer job on a 5 mm machine");
  // Allowed: said in the reply and in the status.
  const json allowed =
      c.request({{"cmd", "submit"}, {"job", {{"path", big}, {"allow_interference", true}}}});
  // big.json is for a 12 mm ball: still refused on this 5 mm machine, the tool check stands.
  expect_error(allowed, "ball radius of 12 mm", "big.json allowed, on a 5 mm machine");
  EXPECT_TRUE(alive());
}

TEST_F(ServeHardening, InterferenceAllowedIsStatedAndAJobWithTheChamfersToolRuns) {
  const std::string big = (dir_ / "big.json").string();
  ASSERT_EQ(
      ncd("chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 12 --width 0.7 -q -o " + big)
          .status,
      0);
  launch("simulated");  // the documented defaults: a chamfer brings its own ball radius
  HardeningClient c(socket_);
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", big}}}}), "allow_interference",
               "big.json");
  const json r =
      c.request({{"cmd", "submit"}, {"job", {{"path", big}, {"allow_interference", true}}}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  EXPECT_NE(r.value("warning", "").find("interference"), std::string::npos) << r.dump();
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  const json s = wait_for(c, "done");
  EXPECT_TRUE(s.value("interference_allowed", false)) << s.dump();
}

TEST_F(ServeHardening, AHeavyWeightNurbsIsRefusedAtSubmit) {
  // The rational NURBS of issue 11 (the walk crawled, then jumped 28 mm in one period) is
  // refused when the job is read, naming the weight, its ratio and the limit; nothing runs.
  const std::string crawl = write("crawl.json",
                                  R"({"nurbs": {"degree": 2, "knots": [0,0,0,1,1,2,2,2],
          "weights": [1,0.7071067811865476,1576461,0.7071067811865476,1],
          "points": [[0,20,0],[-20,20,0],[-20,0,0],[-20,-20,0],[0,-20,0]]}})");
  launch("simulated");
  HardeningClient c(socket_);
  expect_error(c.request({{"cmd", "submit"},
                          {"job", {{"path", crawl}}},
                          {"setpoints", (dir_ / "crawl.csv").string()}}),
               "weight[2] = 1576461", "heavy weight");
  const json s = c.request({{"cmd", "status"}});
  EXPECT_NE(s["state"], "running") << s.dump();
  EXPECT_FALSE(fs::exists(dir_ / "crawl.csv"));
  EXPECT_TRUE(alive());
}

}  // namespace

namespace {

// [live_limits] in the serve config: each rule "error" or "report"; anything else is refused at
// start (exit 2) naming the key and the two words.
TEST_F(ServeHardening, LiveLimitActionsAreCheckedInTheConfig) {
  const std::string bad = write("bad.toml", "[live_limits]\naccel = \"ignore\"\n");
  auto r = ncd("serve --config " + bad + " --listen unix:" + (dir_ / "x.sock").string());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("live_limits.accel"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("\"report\""), std::string::npos) << r.err;
  const std::string unknown = write("unknown.toml", "[live_limits]\nspeed = \"error\"\n");
  r = ncd("serve --config " + unknown + " --listen unix:" + (dir_ / "x.sock").string());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("feed, accel, jerk, chord"), std::string::npos) << r.err;
  // "report" on every rule is accepted: the service starts and answers.
  launch("simulated",
         "[live_limits]\nfeed = \"report\"\naccel = \"report\"\njerk = \"report\"\n"
         "chord = \"report\"\n");
  HardeningClient c(socket_);
  const json s = c.request({{"cmd", "status"}});
  EXPECT_TRUE(s["ok"].get<bool>()) << s.dump();
  EXPECT_EQ(s["live_limit_violations"]["accel"], 0);
}

}  // namespace
