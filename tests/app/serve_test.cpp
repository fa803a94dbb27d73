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

#include "tests/app/serve_fixture.hpp"
#include "tests/common/test_paths.hpp"

namespace {

using ncd::test::slurp;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

using Client = ncd::test::ServeClient;

class Serve : public ncd::test::ServeFixture {};

TEST_F(Serve, JobOverTheSocketGivesReplaysSetpoints) {
  const std::string cubic = write("cubic.json", ncd::test::kCubicJson);
  // The whole program around the path (docs/whole-program.md), as replay walks it.
  ASSERT_EQ(ncd("replay " + cubic + " -q --setpoints " + (dir_ / "replay.csv").string()).status, 0);
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
  // The whole job ends back over the drill axis at the clearance plane `ncd chamfer` writes for
  // the same chamfer (an inner edge: out of the bore along the axis).
  ASSERT_EQ(ncd("chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 "
                "--rod-radius 1.8 --non-knife-angle 93 -q -o " +
                (dir_ / "c.json").string())
                .status,
            0);
  const double safe_z = json::parse(slurp(dir_ / "c.json"))["input"]["safe_z_mm"].get<double>();
  const auto end = s["position"].get<std::vector<double>>();
  EXPECT_NEAR(end[0], 0.0, 1e-9);
  EXPECT_NEAR(end[1], 0.0, 1e-9);
  EXPECT_NEAR(end[2], safe_z, 1e-9);
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
  const std::string cubic = write("cubic.json", ncd::test::kCubicJson);
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

// A program whose G91 G28 Z0 has no stored position to go to (no parameter file): the submit
// is answered with the error naming file:line and the parameter; the service goes on.
TEST_F(Serve, AG28WithNoStoredPositionIsRefusedNamingTheLine) {
  const std::string prog = write("home.ngc",
                                 "G21 G90\nG91 G28 Z0\nG90\nG0 X0 Y0 Z5\n"
                                 "G1 Z-1 F100\nG0 Z5\nM2\n");
  launch("simulated");
  Client c(socket_);
  const json r = c.request({{"cmd", "submit"}, {"job", {{"path", prog}}}});
  EXPECT_FALSE(r["ok"].get<bool>()) << r.dump();
  const std::string error = r.value("error", "");
  EXPECT_NE(error.find("home.ngc:2: G28 moves Z to the stored G28 position, but no parameter "
                       "5163 is known"),
            std::string::npos)
      << error;
  EXPECT_TRUE(c.request({{"cmd", "status"}})["ok"].get<bool>());
}

TEST_F(Serve, ClientLeavingDoesNotStopTheJobAndSigtermExitsZero) {
  const std::string cubic = write("cubic.json", ncd::test::kCubicJson);
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

// The live link (a job streamed to the simulated controller, a hold by the link) is tested in
// process and in simulated time: tests/service/live_link_test.cpp.

TEST_F(Serve, RestartFromALineRunsTheProgramFromThereAndSaysSo) {
  const std::string prog = write("prog.ngc",
                                 "G21 G90 G54\nS1000 M3\nG0 Z5\nG0 X0 Y0\nG1 Z-1 F300\n"
                                 "G1 X10 Y0\nG1 X10 Y10\nG1 X0 Y10\nM5\nM2\n");
  launch("simulated");
  Client c(socket_);
  json r = c.request({{"cmd", "submit"}, {"job", {{"path", prog}}}, {"restart_from", 7}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  const json s = wait_for(c, "done");
  EXPECT_EQ(s["restart_from_line"], 7);
  const auto end = s["position"].get<std::vector<double>>();
  EXPECT_NEAR(end[0], 0.0, 1e-9);
  EXPECT_NEAR(end[1], 10.0, 1e-9);
  EXPECT_NEAR(end[2], -1.0, 1e-9);
  // 10 + 10 mm from line 7's start (10, 0, -1): F300 for 20 mm is at least 4 s of motion.
  EXPECT_GE(s["t_s"].get<double>(), 4.0);
  EXPECT_LT(s["t_s"].get<double>(), 6.0);
  // Refusals name the key.
  for (const json& bad :
       {json{{"cmd", "submit"}, {"job", {{"path", prog}}}, {"restart_from", 11}},
        json{{"cmd", "submit"}, {"job", {{"path", prog}}}, {"restart_from", "7"}},
        json{{"cmd", "submit"}, {"job", {{"path", prog}}}, {"clearance_z_mm", 5}},
        json{{"cmd", "submit"},
             {"job",
              {{"pipe-radius", 18}, {"drill-radius", 13}, {"ball-radius", 3}, {"width", 0.7}}},
             {"restart_from", 2}}}) {
    r = c.request(bad);
    EXPECT_FALSE(r["ok"].get<bool>()) << bad.dump();
    EXPECT_NE(r["error"].get<std::string>().find("restart_from"), std::string::npos) << r.dump();
  }
}

}  // namespace
