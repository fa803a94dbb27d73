// `ncd replay`: walk a path against a simulated clock (no sleeping) and report what the machine
// would do: setpoints per period, a report in numbers, and a plot of the feed.
//
// Memory does not grow with the run: setpoints stream to their file, statistics are running
// sums and a fixed histogram, and the plot keeps at most kPlotBuckets time buckets, merging
// neighbours pairwise when they fill up.
#include <charconv>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/commands.hpp"
#include "app/machine_config.hpp"
#include "app/output.hpp"
#include "app/setpoint_sink.hpp"
#include "app/svg_plot.hpp"
#include "core/error.hpp"
#include "motion/job.hpp"
#include "motion/run_stats.hpp"
#include "toolpath/path_io.hpp"

namespace ncd::app {
namespace {

constexpr std::size_t kPlotBuckets = 1500;
constexpr double kMaxSimulatedS = 100.0 * 3600.0;  // a runaway guard: 100 h of motion

struct ReplayArgs {
  std::string path, machine, setpoints, report, plot;
  bool quiet = false;
};

// Fixed-size time buckets for the plot; pairs merge when they fill up.
class PlotBuckets {
 public:
  struct Bucket {
    double t0_s, t1_s, feed_min, feed_max, limit_min, roughness_max;
    std::int64_t n;
  };
  void add(double t_s, double feed, double limit, double roughness_um) {
    if (!buckets_.empty() && buckets_.back().n < per_bucket_) {
      Bucket& b = buckets_.back();
      b.t1_s = t_s;
      b.feed_min = std::min(b.feed_min, feed);
      b.feed_max = std::max(b.feed_max, feed);
      b.limit_min = std::min(b.limit_min, limit);
      b.roughness_max = std::max(b.roughness_max, roughness_um);
      ++b.n;
      return;
    }
    if (buckets_.size() == 2 * kPlotBuckets) merge();
    buckets_.push_back({t_s, t_s, feed, feed, limit, roughness_um, 1});
  }
  const std::vector<Bucket>& buckets() const { return buckets_; }

 private:
  void merge() {
    for (std::size_t i = 0; i < kPlotBuckets; ++i) {
      const Bucket& a = buckets_[2 * i];
      const Bucket& b = buckets_[2 * i + 1];
      buckets_[i] = {a.t0_s,
                     b.t1_s,
                     std::min(a.feed_min, b.feed_min),
                     std::max(a.feed_max, b.feed_max),
                     std::min(a.limit_min, b.limit_min),
                     std::max(a.roughness_max, b.roughness_max),
                     a.n + b.n};
    }
    buckets_.resize(kPlotBuckets);
    per_bucket_ *= 2;
  }
  std::vector<Bucket> buckets_;
  std::int64_t per_bucket_ = 1;
};

Figure replay_figure(const PlotBuckets& plot, const MachineConfig& m, const std::string& source) {
  Series feed{"feed (max/min per bucket)", {}, {}, "#1f77b4"};
  Series limit{"feed limit at the position", {}, {}, "#d62728", true};
  Series rough{"predicted R_max", {}, {}, "#9467bd"};
  for (const auto& b : plot.buckets()) {
    const double tm = 0.5 * (b.t0_s + b.t1_s);
    feed.x.insert(feed.x.end(), {b.t0_s, b.t1_s});
    feed.y.insert(feed.y.end(), {b.feed_max, b.feed_min});
    limit.x.push_back(tm);
    limit.y.push_back(b.limit_min);
    rough.x.push_back(tm);
    rough.y.push_back(b.roughness_max);
  }
  Figure fig;
  fig.title = "ncd replay: " + source;
  fig.x_label = "time (s)";
  Panel p1{"feed against time",
           "feed (mm/min)",
           {feed, limit},
           {{m.limits.max_feed_mm_per_min, "machine maximum feed"}},
           {}};
  Panel p2{"roughness predicted by the ball-end model (Choi)",
           "R_max (um)",
           {rough},
           {{m.cutting.roughness_target_um, "target"}},
           {{0.0, m.cutting.roughness_target_um, "within the target"}}};
  fig.panels = {p1, p2};
  return fig;
}

nlohmann::ordered_json report_json(const motion::RunStats& st, const MachineConfig& m,
                                   const std::string& source, const motion::Job& job,
                                   double lookahead_ns) {
  nlohmann::ordered_json j;
  j["path"] = source;
  j["machine"] = to_json(m);
  j["cycles"] = st.cycles;
  j["duration_s"] = st.duration_s;
  j["path_length_mm"] = st.path_length_mm;
  j["feed_error"] = {{"max_rel", st.feed_error_max_rel},
                     {"rms_rel", st.feed_error_rms_rel()},
                     {"max_abs_mm", st.feed_error_max_abs_mm},
                     {"rel_over_steps_from_mm", motion::kFeedErrorMinStepMm}};
  j["arc_length_drift_mm"] = st.drift_mm();
  j["chord_error_max_mm"] = st.chord_error_max_mm;
  j["accel_max"] = st.accel_max_mm_per_s2;
  j["jerk_max"] = st.jerk_max_mm_per_s3;
  j["feed_max_mm_per_min"] = st.feed_max_mm_per_s * 60.0;
  j["limit_violations"] = st.limit_violations();
  j["limit_violations_by_kind"] = {{"feed", st.violations_feed},
                                   {"accel", st.violations_accel},
                                   {"jerk", st.violations_jerk},
                                   {"chord", st.violations_chord}};
  j["roughness_max_um"] = st.roughness_max_um;
  j["roughness_target_um"] = m.cutting.roughness_target_um;
  nlohmann::ordered_json share = nlohmann::ordered_json::object();
  for (std::size_t id = 0; id < st.cycles_by_limit.size(); ++id) {
    if (st.cycles_by_limit[id] == 0) continue;
    share[motion::limit_name(static_cast<std::uint8_t>(id))] =
        static_cast<double>(st.cycles_by_limit[id]) / static_cast<double>(st.cycles);
  }
  j["active_limit_share"] = share;
  j["walker_not_converged"] = st.not_converged;
  j["lookahead_window_high_water"] = {{"samples", job.planner().window_samples_high_water()},
                                      {"mm", job.planner().window_ahead_mm_high_water()}};
  // The cycle's work per period (planner step + path walk); sampling the limit curve ahead
  // is the planner thread's, reported as a total.
  j["step_time_ns"] = {{"median", st.step_time_ns.quantile(0.5)},
                       {"p99", st.step_time_ns.quantile(0.99)},
                       {"max", st.step_time_ns.max()}};
  j["lookahead_sampling_ms"] = lookahead_ns * 1e-6;
  return j;
}

int run_replay(const ReplayArgs& a) {
  const MachineConfig machine =
      a.machine.empty() ? MachineConfig{} : load_machine_config(a.machine);
  const toolpath::Path path = toolpath::read_path_file(a.path);
  motion::JobConfig cfg;
  cfg.limits = machine.limits;
  cfg.cutting = machine.cutting;
  motion::Job job(path, cfg);
  SetpointSink sink(a.setpoints);
  PlotBuckets plot;
  motion::RunStats st;
  st.path_length_mm = job.length_mm();
  double lookahead_ns = 0.0;  // sampling the limit curve for the planner, in total
  const auto wall0 = std::chrono::steady_clock::now();
  auto next_progress = wall0 + std::chrono::seconds(2);
  for (;;) {
    const auto tp = std::chrono::steady_clock::now();
    job.prepare();
    const auto t0 = std::chrono::steady_clock::now();
    const motion::Setpoint sp = job.step();
    const auto t1 = std::chrono::steady_clock::now();
    lookahead_ns += static_cast<double>(std::chrono::nanoseconds(t0 - tp).count());
    const double limit = job.limit_here().feed_mm_per_s;
    const double rough = job.roughness_here_um(sp.v_mm_per_s);
    motion::record(st, cfg, sp, limit, rough,
                   static_cast<double>(std::chrono::nanoseconds(t1 - t0).count()));
    sink.write(sp);
    plot.add(sp.t_s, sp.v_mm_per_s * 60.0, limit * 60.0, rough);
    if (sp.done) break;
    if (sp.t_s > kMaxSimulatedS) {
      throw std::runtime_error("the motion did not finish within 100 h of simulated time");
    }
    if (!a.quiet && t1 > next_progress) {
      std::cerr << "replay: " << static_cast<int>(100.0 * sp.s_mm / job.length_mm()) << " % ("
                << sp.t_s << " s simulated)\n";
      next_progress = t1 + std::chrono::seconds(2);
    }
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  const std::string source = path.source;
  if (!a.report.empty())
    write_output(a.report, report_json(st, machine, source, job, lookahead_ns).dump(1) + "\n");
  if (!a.plot.empty()) write_output(a.plot, render_svg(replay_figure(plot, machine, source)));
  sink.commit();
  if (!a.quiet) {
    std::fprintf(stderr,
                 "replay: %s\n  path length       %.4f mm in %lld periods of %.4g s = %.3f s\n"
                 "  feed              max %.1f mm/min; roughness max %.3f um (target %.3f um)\n"
                 "  feed error        max %.3g, rms %.3g (true arc against planned, steps >= 1 um);"
                 " max %.3g mm\n"
                 "  drift             %.3g mm; chord error max %.3g mm (tolerance %.3g mm)\n"
                 "  accel, jerk max   %.1f mm/s2, %.0f mm/s3; limit violations %lld\n"
                 "  step time         median %.0f ns, p99 %.0f ns; replayed in %.2f s "
                 "(%.0f periods/s)\n",
                 source.c_str(), st.path_length_mm, static_cast<long long>(st.cycles),
                 machine.limits.period_s, st.duration_s, st.feed_max_mm_per_s * 60.0,
                 st.roughness_max_um, machine.cutting.roughness_target_um, st.feed_error_max_rel,
                 st.feed_error_rms_rel(), st.feed_error_max_abs_mm, st.drift_mm(),
                 st.chord_error_max_mm, machine.limits.chord_tolerance_mm, st.accel_max_mm_per_s2,
                 st.jerk_max_mm_per_s3, static_cast<long long>(st.limit_violations()),
                 st.step_time_ns.quantile(0.5), st.step_time_ns.quantile(0.99), wall_s,
                 static_cast<double>(st.cycles) / std::max(wall_s, 1e-9));
  }
  return 0;
}

}  // namespace

void register_replay(CLI::App& app, Runner& run) {
  auto a = std::make_shared<ReplayArgs>();
  CLI::App* c = app.add_subcommand(
      "replay",
      "Walk a path in simulated time at the roughness-bounded feed (paper 004) and report it. "
      "PATH: the JSON of `ncd chamfer`, a JSON path file ({\"nurbs\": …} or {\"polyline\": …}), "
      "or RS-274/NGC with G0/G1 and G5.2/G5.3 NURBS blocks.");
  c->add_option("path", a->path, "path file")->required();
  c->add_option("--machine", a->machine,
                "machine file (TOML: period, limits, tolerances, [cutting]); default: the "
                "documented defaults, see config/machine.example.toml");
  c->add_option("--setpoints", a->setpoints,
                "CSV of one row per period: t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit");
  c->add_option("--report", a->report, "JSON report of the run");
  c->add_option("--plot", a->plot, "SVG plot of feed and predicted roughness against time");
  c->add_flag("-q,--quiet", a->quiet, "no progress or summary on standard error");
  c->callback([a, &run] { run = [a] { return run_replay(*a); }; });
}

}  // namespace ncd::app
