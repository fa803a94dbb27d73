// A part's job over `ncd serve`'s control socket (docs/service.md "Jobs", docs/part.md): the
// service runs the whole program `ncd chamfer --part` writes for the same part and machine file,
// so its setpoints are those `ncd replay` walks for that program, byte for byte; a bad part is
// refused with the hole and the key named, and nothing is submitted.
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "api/intake.hpp"
#include "service/machine_config.hpp"
#include "tests/app/serve_fixture.hpp"
#include "tests/common/test_paths.hpp"

namespace {

using ncd::test::slurp;
using nlohmann::json;

const std::string kServedManifold = std::string(NCD_SOURCE_DIR) + "/examples/manifold.toml";
const std::string kRotary = std::string(NCD_SOURCE_DIR) + "/examples/machine-rotary.toml";

class ServePart : public ncd::test::ServeFixture {};

TEST_F(ServePart, PartJobWalksTheProgramChamferPartWrites) {
  const std::string program = (dir_ / "manifold.ngc").string();
  ASSERT_EQ(ncd("chamfer --part " + kServedManifold + " --machine " + kRotary + " -q -o " + program)
                .status,
            0);
  const auto replay = ncd("replay " + program + " --machine " + kRotary +
                          " --start 0,0,50 -q --setpoints " + (dir_ / "replay.csv").string());
  ASSERT_EQ(replay.status, 0) << replay.err;
  launch("simulated", "machine = \"" + kRotary + "\"\n");
  ncd::test::ServeClient c(socket_);
  for (const bool by_text : {false, true}) {
    SCOPED_TRACE(by_text ? "part_toml" : "part");
    const std::string csv = (dir_ / (by_text ? "serve-text.csv" : "serve-file.csv")).string();
    const json job =
        by_text ? json{{"part_toml", slurp(kServedManifold)}} : json{{"part", kServedManifold}};
    json r =
        c.request({{"cmd", "submit"}, {"job", job}, {"start_mm", {0, 0, 50}}, {"setpoints", csv}});
    ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
    ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
    const json s = wait_for(c, "done", 12000);
    EXPECT_NEAR(s["progress"].get<double>(), 1.0, 1e-12);
    const std::string served = slurp(csv), replayed = slurp(dir_ / "replay.csv");
    EXPECT_GT(served.size(), 100000u);
    EXPECT_TRUE(served == replayed) << "the served part's setpoints differ from the replay's ("
                                    << served.size() << " and " << replayed.size() << " bytes)";
  }
  EXPECT_EQ(terminate(), 0);
}

TEST_F(ServePart, BadPartIsRefusedNamingTheHoleAndKeyAndNothingIsSubmitted) {
  launch("simulated", "machine = \"" + kRotary + "\"\n");
  ncd::test::ServeClient c(socket_);
  std::string text = slurp(kServedManifold);
  // An unknown key in hole 7.
  std::string bad = text;
  const std::string tilt = "tilt_deg = 30.0\nazimuth_deg = 0.0\nedge = \"outer\"";
  const std::size_t at = bad.find(tilt);
  ASSERT_NE(at, std::string::npos);
  bad.replace(at, tilt.size(), "tilt = 30.0\nazimuth_deg = 0.0\nedge = \"outer\"");
  json r = c.request({{"cmd", "submit"}, {"job", {{"part_toml", bad}}}});
  expect_error(r, "hole 7", "an unknown key");
  expect_error(r, "tilt", "an unknown key");
  // A hole that cannot be cut: the inner edge of a lateral.
  bad = text;
  bad.replace(at, tilt.size(), "tilt_deg = 30.0\nazimuth_deg = 0.0\nedge = \"inner\"");
  r = c.request({{"cmd", "submit"}, {"job", {{"part_toml", bad}}}});
  expect_error(r, "hole 7 (\"lateral 90\")", "a refused hole");
  expect_error(r, "lacks that tilt", "a refused hole");
  // A part file that does not exist; both keys; a key of another job.
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"part", "/nonexistent/part.toml"}}}}),
               "/nonexistent/part.toml", "a missing file");
  expect_error(
      c.request({{"cmd", "submit"}, {"job", {{"part", kServedManifold}, {"part_toml", text}}}}),
      "not both", "both keys");
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"part", kServedManifold}, {"feed", 100}}}}),
               "\"feed\"", "a key of another job");
  const json s = c.request({{"cmd", "status"}});
  EXPECT_EQ(s["state"], "idle") << s.dump();
  EXPECT_TRUE(s["job"].is_null()) << s.dump();
  EXPECT_EQ(s["setpoints"], 0) << s.dump();
  expect_error(c.request({{"cmd", "start"}}), "nothing to start", "a start after the refusals");
  EXPECT_EQ(terminate(), 0);
}

// What the dashboard lists of a part's job (docs/web-dashboard.md, "The programmed path and the
// listing"): the program `ncd chamfer --part --machine` writes, line for line, under the part
// file's name. The request handler the socket, the page and MQTT share, in process.
TEST_F(ServePart, ThePagesListingIsTheProgramChamferPartWrites) {
  const auto r = ncd("chamfer --part " + kServedManifold + " --machine " + kRotary + " -q");
  ASSERT_EQ(r.status, 0) << r.err;
  boost::asio::io_context io;
  ncd::api::ServiceConfig config;
  config.machine = ncd::service::load_machine_config(kRotary);
  config.clock = ncd::motion::ClockKind::Simulated;
  config.realtime = false;
  ncd::api::Intake intake(io, config);
  const json reply = intake.handle(
      {{"cmd", "submit"}, {"job", {{"part", kServedManifold}}}, {"start_mm", {0, 0, 50}}});
  ASSERT_TRUE(reply["ok"].get<bool>()) << reply.dump();
  const auto view = intake.program_view();
  ASSERT_TRUE(view);
  EXPECT_EQ((*view)["listing_file"], kServedManifold);
  std::vector<std::string> want;
  std::istringstream in(r.out);
  for (std::string line; std::getline(in, line);) want.push_back(line);
  ASSERT_TRUE((*view)["listing"].is_array()) << view->dump().substr(0, 400);
  EXPECT_EQ((*view)["listing"].get<std::vector<std::string>>(), want);
  EXPECT_GT(want.size(), 900u);
}

}  // namespace
