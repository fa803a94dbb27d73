// `ncd bench latency --with-service-io` (app/bench_service_io.cpp): the real executable for one
// round of 1 s phases against a mosquitto it starts itself. Checked: the report's structure, the
// order of the phases, the ratio recomputed from the two p99s, every wake-up in each histogram,
// and that the "with" phase really delivered (WebSocket frames and MQTT messages counted by the
// bench's own clients, consistent with the rate: more than none, never more than the rate allows
// over the phase). Latency values are never asserted: the machine is shared and loaded.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::CmdResult;
using ncd::test::slurp;

class BenchServiceIoCli : public ncd::test::Cli {};

bool have_mosquitto() {
  for (const char* p : {"/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto", "/usr/bin/mosquitto",
                        "/sbin/mosquitto"}) {
    if (::access(p, X_OK) == 0) return true;
  }
  return false;
}

std::int64_t histogram_total(const nlohmann::json& bins) {
  std::int64_t n = 0;
  for (const auto& b : bins) n += b["count"].get<std::int64_t>();
  return n;
}

TEST_F(BenchServiceIoCli, BadArgumentsExit2BeforeAnyBroker) {
  EXPECT_EQ(ncd("bench latency --with-service-io --seconds 1 --rounds 0").status, 2);
  EXPECT_EQ(ncd("bench latency --with-service-io --seconds 1 --rounds 101").status, 2);
  const CmdResult hz = ncd("bench latency --with-service-io --seconds 1 --status-hz 60");
  EXPECT_EQ(hz.status, 2);
  EXPECT_NE(hz.err.find("--status-hz"), std::string::npos) << hz.err;
  EXPECT_NE(hz.err.find("50"), std::string::npos) << hz.err;  // the limit
  const CmdResult lone = ncd("bench latency --seconds 1 --rounds 2 --no-cyclictest");
  EXPECT_EQ(lone.status, 2);
  EXPECT_NE(lone.err.find("--with-service-io"), std::string::npos) << lone.err;
  EXPECT_EQ(ncd("bench latency --with-service-io --stress --seconds 1").status, 2);
  const CmdResult help = ncd("bench latency --help");
  for (const char* flag : {"--with-service-io", "--rounds", "--status-hz", "--mqtt-broker"}) {
    EXPECT_NE(help.out.find(flag), std::string::npos) << flag;
  }
}

TEST_F(BenchServiceIoCli, OneRoundMeasuresBothPhasesAndTheObserversDeliverAtTheirRate) {
  if (!have_mosquitto()) {
    GTEST_SKIP() << "mosquitto is not installed (apt-get install mosquitto); the bench needs a "
                    "real broker";
  }
  const std::string json_out = (dir_ / "bench.json").string();
  const CmdResult r = ncd(
      "bench latency --with-service-io --seconds 1 --rounds 1 --status-hz 50 --json " + json_out);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("p99 with / without"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("load average before"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(json_out));
  EXPECT_EQ(j["mode"], "with_service_io");
  EXPECT_EQ(j["rounds"], 1);
  EXPECT_EQ(j["broker"]["started_by_bench"], true);
  ASSERT_EQ(j["phases"].size(), 2U);
  EXPECT_EQ(j["phases"][0]["kind"], "without");  // the first round: without, then with
  EXPECT_EQ(j["phases"][1]["kind"], "with");

  const double hz = 50.0;
  for (const auto& p : j["phases"]) {
    for (const char* key : {"p50", "p99", "p999", "max"}) {
      ASSERT_TRUE(p["lateness_us"][key].is_number()) << key;
    }
    EXPECT_GT(p["periods"].get<std::int64_t>(), 0);
    EXPECT_EQ(p["setpoints_lost"], 0);
    const double job_s = p["job_s"].get<double>();
    EXPECT_GT(job_s, 0.9);  // the phase lasts --seconds, then a stop ramp
    if (p["kind"] == "without") {
      EXPECT_TRUE(p["websocket_frames"].is_null());
      EXPECT_EQ(p["mqtt_messages"]["status"], 0);  // no bridge publishes in this phase
      continue;
    }
    // Counted by the bench's own clients while the job ran: at the rate, never above it (one
    // frame per 1/hz at most, plus the one due at the window's start and a bridge's catch-up).
    for (const char* kind : {"websocket_frames", "mqtt_messages"}) {
      const std::int64_t n = p[kind]["status"].get<std::int64_t>();
      EXPECT_GT(n, 0) << kind;
      EXPECT_LE(static_cast<double>(n), hz * job_s + 3.0) << kind;
      EXPECT_GE(static_cast<double>(n), 0.25 * hz * job_s) << kind << " (a loaded machine)";
      // The job's events (submitted, started, …) reach both observers.
      EXPECT_GE(p[kind]["events"].get<std::int64_t>(), 2) << kind;
      EXPECT_GT(p[kind]["bytes"].get<std::int64_t>(), 0) << kind;
    }
    EXPECT_TRUE(p["websocket_error"].is_null()) << p["websocket_error"];
    // What the subscriber got was published by the bridge (one in flight at the snapshot).
    EXPECT_LE(p["mqtt_messages"]["status"].get<std::int64_t>(),
              p["bridge"]["status_published"].get<std::int64_t>() + 1);
    EXPECT_EQ(p["bridge"]["events_dropped"], 0);
  }
  // Each kind sums its phases, and its histogram holds every wake-up.
  for (const char* kind : {"without", "with"}) {
    const nlohmann::json& k = j[kind];
    EXPECT_EQ(k["phases"], 1) << kind;
    const auto& phase = j["phases"][std::string(kind) == "without" ? 0 : 1];
    EXPECT_EQ(k["periods"], phase["periods"]) << kind;
    // periods = wake-ups + periods caught up back to back (motion/cycle.cpp).
    EXPECT_EQ(histogram_total(k["lateness_histogram"]),
              k["periods"].get<std::int64_t>() - k["caught_up_periods"].get<std::int64_t>())
        << kind;
    EXPECT_DOUBLE_EQ(k["lateness_us"]["p99"].get<double>(),
                     phase["lateness_us"]["p99"].get<double>())
        << kind;
  }
  const double p0 = j["without"]["lateness_us"]["p99"].get<double>();
  const double p1 = j["with"]["lateness_us"]["p99"].get<double>();
  ASSERT_GT(p0, 0.0);
  EXPECT_DOUBLE_EQ(j["p99_ratio"].get<double>(), p1 / p0);
  EXPECT_EQ(j["p99_ratio_limit"], 1.1);
  EXPECT_EQ(j["p99_within_limit"], p1 / p0 <= 1.1);
}

}  // namespace
