// `ncd bench latency`: how late the real cycle wakes on this machine, beside cyclictest.
//
//   ncd run (N s)                                   cyclictest run (N s, after ncd)
//   ┌──────────────┐  ring  ┌──────────┐            ┌──────────────────────────────┐
//   │ Cycle thread │ ─────► │ consumer │ pop+count  │ cyclictest -m -q -t1 -p… -i… │
//   │ SCHED_FIFO   │        └──────────┘            └──────────────────────────────┘
//   │ planner+walk │   [--stress: a busy thread pinned to the highest-numbered CPU, both runs]
//   └──────────────┘
//
// The job is a long spiral NURBS (as bench/replay_bench.cpp) under the default machine limits,
// sized not to end within N s; should it end anyway, a new job starts (a new Cycle) and the
// statistics add up. After N s: Cycle::stop (a jerk-limited stop on the path) and join. There
// are no output sinks: setpoints are popped and counted, and none may be lost. cyclictest runs
// after ncd, not beside it, so the two do not compete for the CPU; its p99 is the floor this
// machine allows, and ncd's p99 should stay within 1.5x of it.
//
// Cycle has no CPU affinity option, so the cycle thread is not pinned (nor is cyclictest, to
// keep the two runs alike): --stress pins its busy thread to the highest-numbered CPU and the
// scheduler places the measuring threads.
#include <sched.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "app/bench_service_io.hpp"
#include "app/commands.hpp"
#include "app/cyclictest.hpp"
#include "app/latency_report.hpp"
#include "core/error.hpp"
#include "core/output_file.hpp"
#include "geometry/spiral.hpp"
#include "motion/cycle.hpp"

namespace ncd::app {
namespace {

using Clock = std::chrono::steady_clock;

constexpr double kP99RatioLimit = 1.5;
constexpr int kMaxSpiralTurns = 900;  // r from 100 mm down to 10 mm at 0.1 mm pitch

struct BenchLatencyArgs {
  int seconds = 0;
  double period_ms = 4.0;
  std::string json;
  bool stress = false, no_cyclictest = false;
  // --with-service-io (app/bench_service_io.hpp): the service without and with its observers.
  bool with_service_io = false;
  int rounds = 2;
  double status_hz = 50.0;
  std::string mqtt_broker;
};

// Turns whose length (about 2π (100 k − 0.05 k²) mm for k turns) covers `seconds` at the
// machine's maximum feed with half again as margin; at most kMaxSpiralTurns.
int spiral_turns_for(double seconds, double max_feed_mm_per_s) {
  const double needed_mm = 1.5 * seconds * max_feed_mm_per_s + 1000.0;
  for (int k = 1; k < kMaxSpiralTurns; ++k) {
    if (toolpath::spiral_length_mm(k) >= needed_mm) return k;
  }
  return kMaxSpiralTurns;
}

// A busy thread pinned to the highest-numbered CPU this process may use.
class CpuStress {
 public:
  CpuStress() {
    cpu_set_t allowed;
    CPU_ZERO(&allowed);
    if (sched_getaffinity(0, sizeof allowed, &allowed) == 0) {
      for (int c = CPU_SETSIZE - 1; c >= 0; --c) {
        if (CPU_ISSET(c, &allowed)) {
          cpu_ = c;
          break;
        }
      }
      allowed_cpus_ = CPU_COUNT(&allowed);
    }
    std::promise<int> pinned;
    std::future<int> pinned_rc = pinned.get_future();
    thread_ = std::thread([this, &pinned] { spin(pinned); });
    const int rc = pinned_rc.get();
    note_ =
        "stress: a busy thread on CPU " + std::to_string(cpu_) +
        (rc == 0
             ? " (pinned, the highest-numbered of " + std::to_string(allowed_cpus_) + " allowed)"
             : " (not pinned: sched_setaffinity failed, errno " + std::to_string(rc) + ")") +
        "; the cycle thread and cyclictest are not pinned (Cycle has no affinity option)" +
        (allowed_cpus_ <= 1 ? "; only one CPU: the stress shares it with the cycle" : "");
  }
  ~CpuStress() {
    stop_.store(true, std::memory_order_relaxed);
    thread_.join();
  }
  CpuStress(const CpuStress&) = delete;
  CpuStress& operator=(const CpuStress&) = delete;
  int cpu() const { return cpu_; }
  const std::string& note() const { return note_; }

 private:
  void spin(std::promise<int>& pinned) {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpu_, &one);
    pinned.set_value(sched_setaffinity(0, sizeof one, &one) == 0 ? 0 : errno);
    std::uint64_t x = 0x9E3779B97F4A7C15ULL;  // xorshift: arithmetic the compiler keeps
    while (!stop_.load(std::memory_order_relaxed)) {
      for (int i = 0; i < 4096; ++i) {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
      }
    }
    sink_.store(x, std::memory_order_relaxed);
  }
  int cpu_ = 0, allowed_cpus_ = 1;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> sink_{0};
  std::thread thread_;
  std::string note_;
};

// What ncd's cycle did over all its jobs.
struct NcdRun {
  motion::CycleStats stats;
  std::int64_t setpoints = 0;          // popped by the consumer
  std::int64_t periods_in_window = 0;  // run before the stop was asked (the rest: the stop ramp)
  int jobs = 0;
  motion::RealtimeGrant grant;
  double wall_s = 0.0;
};

// One Cycle after another on the wall clock until `seconds` have passed, setpoints discarded.
NcdRun run_ncd(const toolpath::Path& path, const motion::JobConfig& cfg, int seconds) {
  NcdRun run;
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(cfg.limits.period_s));
  const auto t0 = Clock::now();
  const auto deadline = t0 + std::chrono::seconds(seconds);
  do {
    motion::CycleOptions opt;
    opt.clock = motion::ClockKind::Wall;
    opt.realtime = true;
    auto cycle = std::make_unique<motion::Cycle>(std::make_unique<motion::Job>(path, cfg), opt);
    std::atomic<bool> cycle_ended{false};
    std::int64_t popped = 0;
    const motion::RealtimeGrant grant = cycle->start();
    std::thread consumer([&] {  // the ring holds 8192 periods: a late start is harmless
      motion::Setpoint sp;
      for (;;) {
        const bool ended = cycle_ended.load(std::memory_order_acquire);
        while (cycle->pop(sp)) ++popped;
        if (ended) return;
        std::this_thread::sleep_for(period / 4);
      }
    });
    if (run.jobs++ == 0) {
      run.grant = grant;
      std::printf("  realtime: %s\n", grant.message.c_str());
      std::fflush(stdout);
    }
    while (!cycle->finished() && Clock::now() < deadline) {
      std::this_thread::sleep_until(
          std::min(deadline, Clock::now() + std::chrono::milliseconds(20)));
    }
    std::int64_t periods_at_stop = -1;  // -1: the job ended by itself
    if (!cycle->finished()) {
      periods_at_stop = cycle->status().periods;
      cycle->stop();
    }
    cycle->join();
    cycle_ended.store(true, std::memory_order_release);
    consumer.join();
    if (!cycle->error().empty()) throw std::runtime_error("the cycle failed: " + cycle->error());
    const motion::CycleStats& s = cycle->stats();
    if (popped + s.setpoints_lost != s.periods) {
      throw std::runtime_error("setpoints popped (" + std::to_string(popped) + ") + lost (" +
                               std::to_string(s.setpoints_lost) + ") != periods (" +
                               std::to_string(s.periods) + ")");
    }
    run.periods_in_window += periods_at_stop >= 0 ? periods_at_stop : s.periods;
    add_stats(run.stats, s);
    run.setpoints += popped;
  } while (Clock::now() < deadline);
  run.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return run;
}

// --with-service-io: the service without and with its observers (app/bench_service_io.hpp).
int run_with_service_io(const BenchLatencyArgs& a) {
  if (a.stress) {
    throw InputError(
        "--stress and --with-service-io do not go together: the second compares the service "
        "with and without its observers on the machine as it is; leave one out");
  }
  ServiceIoBenchArgs s;
  s.seconds = a.seconds;
  s.rounds = a.rounds;
  s.period_ms = a.period_ms;
  s.status_hz = a.status_hz;
  s.broker = a.mqtt_broker;
  s.json = a.json;
  return run_bench_service_io(s);
}

void print_ncd_run(const NcdRun& ncd, const LatencyPercentiles& late) {
  const motion::CycleStats& st = ncd.stats;
  std::printf(
      "ncd cycle: %lld periods in %.2f s (%lld before the stop, %d job%s), %lld setpoints popped, "
      "%lld lost\n"
      "  lateness (us)       p50 %s, p99 %s, p99.9 %s, max %s\n"
      "  late wake-ups %lld, catch-up periods %lld, overruns %lld\n"
      "  compute per period  median %s us, p99 %s us, max %s us\n"
      "  lateness histogram (wake-ups; bars linear in the count):\n%s",
      static_cast<long long>(st.periods), ncd.wall_s, static_cast<long long>(ncd.periods_in_window),
      ncd.jobs, ncd.jobs == 1 ? "" : "s", static_cast<long long>(ncd.setpoints),
      static_cast<long long>(st.setpoints_lost), format_us(late.p50_us).c_str(),
      format_us(late.p99_us).c_str(), format_us(late.p999_us).c_str(),
      format_us(late.max_us).c_str(), static_cast<long long>(st.late_wakeups),
      static_cast<long long>(st.caught_up), static_cast<long long>(st.overruns),
      format_us(st.compute_ns.quantile(0.5) * 1e-3).c_str(),
      format_us(st.compute_ns.quantile(0.99) * 1e-3).c_str(),
      format_us(st.compute_ns.max() * 1e-3).c_str(), format_histogram_us(st.lateness_ns).c_str());
  std::fflush(stdout);
}

// cyclictest's run after ncd's, and why there is no result when there is none.
struct CyclictestStep {
  CyclictestRun run;
  std::string reason = "--no-cyclictest";
};

CyclictestStep run_cyclictest_after(const BenchLatencyArgs& a, double period_us) {
  CyclictestStep ct;
  if (a.no_cyclictest) return ct;
  CyclictestOptions o;
  o.interval_us = static_cast<int>(std::lround(period_us));
  o.seconds = a.seconds;
  o.priority = motion::CycleOptions{}.fifo_priority;
  o.histogram_max_us = std::min(100000, std::max(1000, 4 * o.interval_us));
  ct.run = run_cyclictest(o);
  std::printf("cyclictest: %s\n", ct.run.command.c_str());
  for (const std::string& n : ct.run.notes) std::printf("  note: %s\n", n.c_str());
  if (!ct.run.ok) {
    ct.reason = ct.run.reason;
    std::printf("  no result: %s\n", ct.run.reason.c_str());
  }
  return ct;
}

// What the bench ran besides the two runs: the spiral and the stress thread's note.
struct BenchSetup {
  int turns = 0;
  std::string stress_note;  // empty without --stress
};

nlohmann::ordered_json bench_json(const BenchLatencyArgs& a, const BenchSetup& setup,
                                  const NcdRun& ncd, const LatencyPercentiles& late,
                                  const CyclictestStep& ct, const P99Verdict& verdict) {
  const motion::CycleStats& st = ncd.stats;
  nlohmann::ordered_json j;
  j["seconds"] = a.seconds;
  j["period_ms"] = a.period_ms;
  j["stress"] = a.stress;
  j["stress_note"] = a.stress ? nlohmann::ordered_json(setup.stress_note) : nullptr;
  j["realtime"] = {{"fifo", ncd.grant.fifo},
                   {"memory_locked", ncd.grant.memory_locked},
                   {"cpu_latency_held", ncd.grant.cpu_latency_held},
                   {"message", ncd.grant.message}};
  j["path"] = {{"kind", "spiral NURBS"}, {"turns", setup.turns}};
  j["jobs"] = ncd.jobs;
  j["wall_s"] = ncd.wall_s;
  j["periods"] = st.periods;
  j["periods_before_stop"] = ncd.periods_in_window;
  j["setpoints"] = ncd.setpoints;
  j["setpoints_lost"] = st.setpoints_lost;
  j["lateness_us"] = percentiles_json(late);
  nlohmann::ordered_json bins = nlohmann::ordered_json::array();
  for (const HistogramBin& b : histogram_bins_us(st.lateness_ns)) {
    bins.push_back({{"from_us", b.from_us}, {"to_us", b.to_us}, {"count", b.count}});
  }
  j["lateness_histogram"] = bins;
  j["late_wakeups"] = st.late_wakeups;
  j["caught_up_periods"] = st.caught_up;
  j["overruns"] = st.overruns;
  j["compute_us"] = {{"median", st.compute_ns.quantile(0.5) * 1e-3},
                     {"p99", st.compute_ns.quantile(0.99) * 1e-3},
                     {"max", st.compute_ns.max() * 1e-3}};
  if (ct.run.ok) {
    j["cyclictest"] = {{"lateness_us", percentiles_json(ct.run.percentiles.us)},
                       {"samples", ct.run.histogram.samples()},
                       {"overflows", ct.run.histogram.overflows},
                       {"command", ct.run.command},
                       {"notes", ct.run.notes}};
    j["cyclictest_reason"] = nullptr;
    j["p99_ratio"] = verdict.ratio ? nlohmann::ordered_json(*verdict.ratio) : nullptr;
    j["p99_ratio_limit"] = kP99RatioLimit;
    j["p99_within_limit"] = verdict.ratio ? nlohmann::ordered_json(verdict.within) : nullptr;
  } else {
    j["cyclictest"] = nullptr;
    j["cyclictest_reason"] = ct.reason;
    j["p99_ratio"] = nullptr;
    j["p99_ratio_limit"] = kP99RatioLimit;
    j["p99_within_limit"] = nullptr;
  }
  return j;
}

// The whole subcommand: ncd's run, then cyclictest's, the report on stdout and in --json.
int run_bench_latency(const BenchLatencyArgs& a) {
  if (a.with_service_io) return run_with_service_io(a);
  if (a.seconds <= 0) throw InputError("--seconds must be > 0, got " + std::to_string(a.seconds));
  const double period_us = a.period_ms * 1e3;
  if (!(std::isfinite(period_us) && period_us >= 10.0 && period_us <= 1e6)) {
    throw InputError("--period-ms " + std::to_string(a.period_ms) +
                     " is outside 0.01..1000 ms; give the cycle's period in milliseconds");
  }
  motion::JobConfig cfg;  // default machine limits and cutting parameters
  cfg.limits.period_s = a.period_ms * 1e-3;
  BenchSetup setup;
  setup.turns = spiral_turns_for(a.seconds, cfg.limits.max_feed_mm_per_min / 60.0);
  const toolpath::Path path = toolpath::spiral_path(setup.turns);
  std::printf(
      "ncd bench latency: %d s at a %s ms period, spiral NURBS of %d turns, default "
      "machine limits%s\n",
      a.seconds, format_us(a.period_ms).c_str(), setup.turns, a.stress ? ", under --stress" : "");
  std::unique_ptr<CpuStress> stress;
  if (a.stress) {
    stress = std::make_unique<CpuStress>();
    setup.stress_note = stress->note();
    std::printf("  %s\n", stress->note().c_str());
  }
  std::fflush(stdout);

  const NcdRun ncd = run_ncd(path, cfg, a.seconds);
  const LatencyPercentiles late = percentiles_us_from_ns(ncd.stats.lateness_ns);
  print_ncd_run(ncd, late);
  const CyclictestStep ct = run_cyclictest_after(a, period_us);
  std::vector<LatencyRow> rows = {{"ncd", late}};
  if (ct.run.ok) rows.push_back({"cyclictest", ct.run.percentiles.us});
  std::printf("\n%s", format_latency_table(rows).c_str());
  P99Verdict verdict;
  if (ct.run.ok) {
    verdict = p99_verdict(late.p99_us, ct.run.percentiles.us.p99_us, kP99RatioLimit);
    std::printf("%s\n", verdict.line.c_str());
  }
  const std::int64_t lost = ncd.stats.setpoints_lost;
  std::printf("setpoints lost: %lld\n", static_cast<long long>(lost));
  std::fflush(stdout);

  if (!a.json.empty()) {
    write_output(a.json, bench_json(a, setup, ncd, late, ct, verdict).dump(1) + "\n");
  }
  if (lost != 0) {
    std::fprintf(stderr, "ncd: %lld setpoints lost: the consumer fell behind the cycle\n",
                 static_cast<long long>(lost));
    return 1;
  }
  return 0;
}

}  // namespace

void register_bench(CLI::App& app, Runner& run) {
  CLI::App* bench = app.add_subcommand("bench", "Measurements of this machine");
  bench->require_subcommand(1);
  auto a = std::make_shared<BenchLatencyArgs>();
  CLI::App* c = bench->add_subcommand(
      "latency",
      "Run the real cycle (planner and walker, no output sinks) on a long spiral for N seconds "
      "and report wake-up lateness percentiles, a histogram, overruns and compute time per "
      "period; then cyclictest with the same period, and both in one table");
  c->add_option("--seconds", a->seconds, "how long each run lasts, s")
      ->required()
      ->check(CLI::PositiveNumber);
  c->add_option("--period-ms", a->period_ms, "cycle period, ms")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  c->add_option("--json", a->json, "write the results as JSON to this file");
  c->add_flag("--stress", a->stress, "a busy thread on the highest-numbered CPU during both runs");
  c->add_flag("--no-cyclictest", a->no_cyclictest, "do not run cyclictest");
  c->add_flag("--with-service-io", a->with_service_io,
              "instead: run the service's job in phases without and with its observers (the "
              "dashboard's WebSocket read by a client, MQTT status to a broker), alternated, "
              "--seconds each, and compare the lateness p99 of the two (no cyclictest)");
  c->add_option("--rounds", a->rounds,
                "--with-service-io: rounds of one phase without and one with (order swapped "
                "every round)")
      ->capture_default_str();
  c->add_option("--status-hz", a->status_hz,
                "--with-service-io: status frames per second to the page and MQTT status rate")
      ->capture_default_str();
  c->add_option("--mqtt-broker", a->mqtt_broker,
                "--with-service-io: the broker's URL (anonymous clients); default: the bench "
                "starts mosquitto on a free loopback port");
  c->callback([a, c, &run] {
    for (const char* name : {"--rounds", "--status-hz", "--mqtt-broker"}) {
      if (!a->with_service_io && c->count(name) > 0) {
        throw CLI::ValidationError(name, "goes with --with-service-io only; add it or leave " +
                                             std::string(name) + " out");
      }
    }
    run = [a] { return run_bench_latency(*a); };
  });
}

}  // namespace ncd::app
