// `ncd bench latency`: cyclictest histogram files written here with percentiles counted by hand,
// the text histogram and table against literal text, merging histograms against adding every
// sample, and the real executable run for 1 s (the JSON contract; latency values are never
// asserted, CI machines are noisy).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "app/cyclictest.hpp"
#include "app/latency_report.hpp"
#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::LogHistogram;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace app = ncd::app;

class BenchLatencyCli : public ncd::test::Cli {};

// A --histfile as rt-tests 2.40 writes it: one line per µs below histogram_max_us, one count
// column per thread, then the summary.
std::string histfile(const std::map<int, std::vector<long>>& counts, int threads,
                     int histogram_max_us, const std::vector<long>& overflows,
                     const std::string& max_line) {
  std::ostringstream s;
  s << "# Histogram\n";
  std::vector<long> total(static_cast<std::size_t>(threads), 0);
  char buf[64];
  for (int us = 0; us < histogram_max_us; ++us) {
    std::snprintf(buf, sizeof buf, "%06d", us);
    s << buf;
    for (int t = 0; t < threads; ++t) {
      const auto it = counts.find(us);
      const long c = it == counts.end() ? 0 : it->second[static_cast<std::size_t>(t)];
      total[static_cast<std::size_t>(t)] += c;
      std::snprintf(buf, sizeof buf, " %06ld", c);
      s << buf;
    }
    s << "\n";
  }
  s << "# Total:";
  for (long t : total) {
    std::snprintf(buf, sizeof buf, " %09ld", t);
    s << buf;
  }
  s << "\n# Min Latencies: 00003\n# Avg Latencies: 00004\n" << max_line;
  s << "# Histogram Overflows:";
  for (long o : overflows) {
    std::snprintf(buf, sizeof buf, " %05ld", o);
    s << buf;
  }
  s << "\n# Histogram Overflow at cycle number:\n";
  for (int t = 0; t < threads; ++t) s << "# Thread " << t << ": 00011 00042\n";
  s << "\n";
  return s.str();
}

TEST_F(BenchLatencyCli, ParsesOneThreadHistogramFile) {
  // 1000 samples: 500 at 10 µs, 490 at 11, 9 at 20, 1 at 50. Ranks ceil(q N): p50 the 500th
  // (10), p99 the 990th (11), p99.9 the 999th (20); max from "# Max Latencies".
  const std::string f = write("h1", histfile({{10, {500}}, {11, {490}}, {20, {9}}, {50, {1}}}, 1,
                                             100, {0}, "# Max Latencies: 00050\n"));
  const app::CyclictestHistogram h = app::parse_cyclictest_histogram(slurp(f));
  EXPECT_EQ(h.samples(), 1000);
  EXPECT_EQ(h.overflows, 0);
  ASSERT_EQ(h.count_per_us.size(), 100U);
  EXPECT_EQ(h.count_per_us[11], 490);
  const app::CyclictestPercentiles p = app::cyclictest_percentiles(h);
  EXPECT_FALSE(p.overflowed);
  EXPECT_EQ(p.us.p50_us, 10.0);
  EXPECT_EQ(p.us.p99_us, 11.0);
  EXPECT_EQ(p.us.p999_us, 20.0);
  EXPECT_EQ(p.us.max_us, 50.0);
}

TEST_F(BenchLatencyCli, PercentileRanksOnFourSamples) {
  // 5, 6, 7, 8 µs: p50 is the 2nd (6); p99 and p99.9 the 4th (8).
  const std::string f = write("h4", histfile({{5, {1}}, {6, {1}}, {7, {1}}, {8, {1}}}, 1, 20, {0},
                                             "# Max Latencies: 00008\n"));
  const app::CyclictestPercentiles p =
      app::cyclictest_percentiles(app::parse_cyclictest_histogram(slurp(f)));
  EXPECT_EQ(p.us.p50_us, 6.0);
  EXPECT_EQ(p.us.p99_us, 8.0);
  EXPECT_EQ(p.us.p999_us, 8.0);
  EXPECT_EQ(p.us.max_us, 8.0);
}

TEST_F(BenchLatencyCli, TwoThreadsAndOverflowsFlagThePercentilesBeyondTheHistogram) {
  // Threads summed: 70 at 3 µs, 25 at 4 µs, 5 overflows (>= 50 µs): N = 100. p50 is the 50th
  // (3); the 99th and the 100th are overflows, given as the maximum 210 and flagged.
  const std::string f = write("h2", histfile({{3, {40, 30}}, {4, {20, 5}}}, 2, 50, {3, 2},
                                             "# Max Latencies: 00210 00180\n"));
  const app::CyclictestHistogram h = app::parse_cyclictest_histogram(slurp(f));
  EXPECT_EQ(h.samples(), 100);
  EXPECT_EQ(h.overflows, 5);
  EXPECT_EQ(h.max_us, 210.0);
  const app::CyclictestPercentiles p = app::cyclictest_percentiles(h);
  EXPECT_TRUE(p.overflowed);
  EXPECT_EQ(p.us.p50_us, 3.0);
  EXPECT_EQ(p.us.p99_us, 210.0);
  EXPECT_EQ(p.us.p999_us, 210.0);
}

TEST_F(BenchLatencyCli, MaxFallsBackToTheLastBucketAndBadFilesThrow) {
  const std::string ok = histfile({{7, {2}}, {9, {1}}}, 1, 20, {0}, "");
  EXPECT_EQ(app::parse_cyclictest_histogram(ok).max_us, 9.0);
  EXPECT_EQ(app::cyclictest_percentiles(app::parse_cyclictest_histogram("")).us.p99_us, 0.0);
  std::string bad_total = ok;
  bad_total.replace(bad_total.find("# Total: 000000003"), 18, "# Total: 000000004");
  EXPECT_THROW(app::parse_cyclictest_histogram(bad_total), std::runtime_error);
  try {
    app::parse_cyclictest_histogram("# Histogram\n000001 000002\nlatency high\n");
    FAIL() << "a line of words must not parse";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
}

TEST(BenchLatencyReport, TableIsAlignedInMicroseconds) {
  const std::string t = app::format_latency_table(
      {{"ncd", {12.34, 45.6, 78.9, 123.4}}, {"cyclictest", {10.0, 30.0, 50.0, 87.0}}});
  EXPECT_EQ(t,
            "latency (us)          p50        p99      p99.9        max\n"
            "ncd                  12.3       45.6       78.9        123\n"
            "cyclictest           10.0       30.0       50.0       87.0\n");
  EXPECT_EQ(app::format_us(0.5124), "0.512");
  EXPECT_EQ(app::format_us(3.0), "3.00");
  EXPECT_EQ(app::format_us(1234.4), "1234");
}

TEST(BenchLatencyReport, P99VerdictAgainstTheLimit) {
  const app::P99Verdict at = app::p99_verdict(45.0, 30.0, 1.5);
  ASSERT_TRUE(at.ratio.has_value());
  EXPECT_DOUBLE_EQ(*at.ratio, 1.5);
  EXPECT_TRUE(at.within);
  EXPECT_EQ(at.line, "ncd p99 / cyclictest p99 = 1.50 (limit 1.5): within the limit");
  const app::P99Verdict above = app::p99_verdict(45.6, 30.0, 1.5);
  EXPECT_FALSE(above.within);
  EXPECT_NE(above.line.find("= 1.52"), std::string::npos) << above.line;
  EXPECT_NE(above.line.find("above the limit"), std::string::npos) << above.line;
  const app::P99Verdict none = app::p99_verdict(45.0, 0.0, 1.5);
  EXPECT_FALSE(none.ratio.has_value());
  EXPECT_FALSE(none.within);
  EXPECT_NE(none.line.find("no ratio"), std::string::npos) << none.line;
}

TEST(BenchLatencyReport, HistogramBinsHoldTheirSamplesAndBarsAreLinear) {
  // ns: 0.5 (below 1 ns), 3 x 20 us, 25 us, 2 ms; none near an edge of the 1/8-decade bins.
  const std::vector<double> values_ns = {0.5, 20e3, 20e3, 20e3, 25e3, 2e6};
  LogHistogram h;
  for (double v : values_ns) h.add(v);
  const std::vector<app::HistogramBin> bins = app::histogram_bins_us(h, 8);
  ASSERT_EQ(bins.size(), 4U);
  const std::vector<std::int64_t> counts = {1, 3, 1, 1};
  for (std::size_t i = 0; i < bins.size(); ++i) {
    EXPECT_EQ(bins[i].count, counts[i]) << i;
    if (i > 0) {
      EXPECT_NEAR(bins[i].to_us / bins[i].from_us, std::pow(10.0, 1.0 / 8.0), 1e-12) << i;
    }
  }
  EXPECT_EQ(bins[0].to_us, 1e-3);  // below 1 ns
  for (double v : values_ns) {
    int holders = 0;
    for (const app::HistogramBin& b : bins)
      holders += (v * 1e-3 >= b.from_us && v * 1e-3 < b.to_us);
    EXPECT_EQ(holders, 1) << v;
  }
  EXPECT_EQ(bins[0].from_us, 0.0);
  const std::string text = app::format_histogram_us(h, 8, 40);
  std::istringstream lines(text);
  std::vector<std::string> ls;
  for (std::string l; std::getline(lines, l);) ls.push_back(l);
  ASSERT_EQ(ls.size(), 4U);
  const auto bar = [](const std::string& l) {
    return static_cast<long>(std::count(l.begin(), l.end(), '#'));
  };
  EXPECT_EQ(bar(ls[1]), 40);  // the fullest bin
  EXPECT_EQ(bar(ls[0]), 13);  // round(40 / 3)
  EXPECT_NE(ls[1].find("17.8 -     23.7 us"), std::string::npos) << ls[1];
  EXPECT_EQ(ls[1].substr(ls[1].size() - 3), "| 3");
  EXPECT_THROW(app::histogram_bins_us(h, 7), std::invalid_argument);
}

TEST(BenchLatencyReport, MergeEqualsAddingEverySample) {
  std::mt19937_64 rng(7);
  std::lognormal_distribution<double> lateness_ns(std::log(30e3), 0.8);
  LogHistogram a, b, all;
  a.add(0.25);  // the first bucket too
  all.add(0.25);
  for (int i = 0; i < 20000; ++i) {
    const double v = lateness_ns(rng);
    (i % 3 == 0 ? a : b).add(v);
    all.add(v);
  }
  for (LogHistogram* dst_start : {static_cast<LogHistogram*>(nullptr), &a}) {
    LogHistogram merged;
    if (dst_start) merged = *dst_start;
    if (!dst_start) app::merge_into(merged, a);
    app::merge_into(merged, b);
    EXPECT_EQ(merged.count(), all.count());
    EXPECT_EQ(merged.max(), all.max());
    EXPECT_EQ(merged.buckets(), all.buckets());
    for (double q : {0.5, 0.99, 0.999}) EXPECT_EQ(merged.quantile(q), all.quantile(q)) << q;
  }
}

TEST_F(BenchLatencyCli, InvalidArgumentsAreInvalidInput) {
  EXPECT_EQ(ncd("bench").status, 2);
  EXPECT_EQ(ncd("bench latency").status, 2);  // --seconds is required
  EXPECT_EQ(ncd("bench latency --seconds 0 --no-cyclictest").status, 2);
  EXPECT_EQ(ncd("bench latency --seconds 1 --period-ms -4 --no-cyclictest").status, 2);
  const CmdResult help = ncd("bench latency --help");
  EXPECT_EQ(help.status, 0);
  for (const char* flag : {"--seconds", "--period-ms", "--json", "--stress", "--no-cyclictest"}) {
    EXPECT_NE(help.out.find(flag), std::string::npos) << flag;
  }
}

// The keys every run writes; periods ≈ 250 per second at 4 ms (a loose band: a stop ramp follows
// the window, and the wall clock of a loaded machine may lag).
void expect_ncd_contract(const nlohmann::json& j, int seconds) {
  for (const char* key :
       {"seconds", "period_ms", "stress", "realtime", "periods", "periods_before_stop", "setpoints",
        "setpoints_lost", "lateness_us", "lateness_histogram", "late_wakeups", "caught_up_periods",
        "overruns", "compute_us", "cyclictest", "p99_ratio"}) {
    ASSERT_TRUE(j.contains(key)) << key;
  }
  for (const char* key : {"p50", "p99", "p999", "max"}) {
    ASSERT_TRUE(j["lateness_us"][key].is_number()) << key;
  }
  for (const char* key : {"median", "p99", "max"}) {
    ASSERT_TRUE(j["compute_us"][key].is_number()) << key;
  }
  for (const char* key : {"fifo", "memory_locked", "message"}) {
    ASSERT_TRUE(j["realtime"].contains(key)) << key;
  }
  EXPECT_EQ(j["seconds"].get<int>(), seconds);
  EXPECT_EQ(j["period_ms"].get<double>(), 4.0);
  // What stays true on a loaded machine (no rates: a busy machine runs fewer periods in the
  // window, and that is what the lateness figures are for). Nothing is lost; every period is
  // accounted for, run at its own wake-up or caught up back to back after a late one; and the
  // time base never runs ahead of the wall clock: at most one period per elapsed period (one
  // more per job, whose first deadline is one period after its start).
  const auto periods = j["periods"].get<std::int64_t>();
  EXPECT_GT(periods, 0);
  EXPECT_EQ(j["setpoints_lost"].get<std::int64_t>(), 0);
  EXPECT_EQ(j["setpoints"].get<std::int64_t>(), periods);
  std::int64_t in_bins = 0;
  for (const auto& b : j["lateness_histogram"]) in_bins += b["count"].get<std::int64_t>();
  EXPECT_GT(in_bins, 0);
  EXPECT_EQ(in_bins + j["caught_up_periods"].get<std::int64_t>(), periods);  // one per wake-up
  EXPECT_LE(j["periods_before_stop"].get<std::int64_t>(), periods);
  EXPECT_LE(static_cast<double>(periods) * 0.004,
            j["wall_s"].get<double>() + 0.004 * j["jobs"].get<double>() + 1e-9);
  const auto& late = j["lateness_us"];
  EXPECT_LE(late["p50"].get<double>(), late["p99"].get<double>());
  EXPECT_LE(late["p99"].get<double>(), late["p999"].get<double>());
  EXPECT_LE(late["p999"].get<double>(), late["max"].get<double>());
}

TEST_F(BenchLatencyCli, OneSecondWithoutCyclictest) {
  const std::string json_out = (dir_ / "latency.json").string();
  const CmdResult r =
      ncd("bench latency --seconds 1 --period-ms 4 --json " + json_out + " --no-cyclictest");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const auto j = nlohmann::json::parse(slurp(json_out));
  expect_ncd_contract(j, 1);
  EXPECT_FALSE(j["stress"].get<bool>());
  EXPECT_TRUE(j["cyclictest"].is_null());
  EXPECT_EQ(j["cyclictest_reason"].get<std::string>(), "--no-cyclictest");
  EXPECT_NE(r.out.find("realtime: cycle on the wall clock"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("latency (us)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("setpoints lost: 0"), std::string::npos) << r.out;
}

TEST_F(BenchLatencyCli, OneSecondUnderStress) {
  const std::string json_out = (dir_ / "latency.json").string();
  const CmdResult r =
      ncd("bench latency --seconds 1 --json " + json_out + " --no-cyclictest --stress");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const auto j = nlohmann::json::parse(slurp(json_out));
  expect_ncd_contract(j, 1);
  EXPECT_TRUE(j["stress"].get<bool>());
  EXPECT_NE(j["stress_note"].get<std::string>().find("busy thread on CPU"), std::string::npos);
}

bool on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "");
  for (std::string d; std::getline(dirs, d, ':');) {
    if (!d.empty() && access((d + "/" + program).c_str(), X_OK) == 0) return true;
  }
  return false;
}

TEST_F(BenchLatencyCli, OneSecondBesideCyclictest) {
  if (!on_path("cyclictest")) {
    GTEST_SKIP() << "cyclictest is not installed (Debian package rt-tests)";
  }
  const std::string json_out = (dir_ / "latency.json").string();
  const CmdResult r = ncd("bench latency --seconds 1 --period-ms 4 --json " + json_out);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const auto j = nlohmann::json::parse(slurp(json_out));
  expect_ncd_contract(j, 1);
  if (j["cyclictest"].is_null()) {
    // rt-tests 2.40 refuses to run without the right to real-time scheduling.
    ASSERT_TRUE(j["cyclictest_reason"].is_string());
    GTEST_SKIP() << "cyclictest did not run here: " << j["cyclictest_reason"].get<std::string>();
  }
  const auto& ct = j["cyclictest"];
  for (const char* key : {"p50", "p99", "p999", "max"}) {
    ASSERT_TRUE(ct["lateness_us"][key].is_number()) << key;
  }
  // cyclictest wakes at most once per interval over its -D1s (it does not catch up: a loaded
  // machine gives fewer samples, never more).
  EXPECT_GT(ct["samples"].get<double>(), 0.0);
  EXPECT_LE(ct["samples"].get<double>(), 1.0 / 0.004 + 1.0);
  EXPECT_NE(ct["command"].get<std::string>().find("-i4000"), std::string::npos);
  EXPECT_TRUE(j["p99_ratio_limit"].is_number());
  EXPECT_NE(r.out.find("\ncyclictest "), std::string::npos) << r.out;  // its row of the table
}

}  // namespace
