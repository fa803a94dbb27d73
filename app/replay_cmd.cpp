// `ncd replay`: walk a path against a simulated clock (no sleeping) and report what the machine
// would do: setpoints per period, a report in numbers, and a plot of the feed. With --blocks,
// every setpoint also goes through the block encoder (link/block_encoder.hpp), which writes
// the NC program a DNC link would carry, within the budget of the machine file's [link].
//
// The job runs in the service library (service/service.hpp, docs/service.md), as `ncd serve`'s
// jobs do, with the simulated clock and no cycle thread: Service::poll() runs each period and
// hands its setpoint to ReplayRecorder (a SetpointSink) while the job still stands where that
// setpoint left it, which is where replay reads the feed limit and the predicted roughness.
//
// Memory does not grow with the run: setpoints and blocks stream to their files, statistics
// are running sums and fixed histograms, and the plot keeps at most kPlotBuckets time buckets,
// merging neighbours pairwise when they fill up.
#include <charconv>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>

#include "app/commands.hpp"
#include "app/svg_plot.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/output_file.hpp"
#include "gcode/path_io.hpp"
#include "link/block_encoder.hpp"
#include "link/program_blocks.hpp"
#include "motion/job.hpp"
#include "motion/run_stats.hpp"
#include "motion/tool_use.hpp"
#include "service/job_checks.hpp"
#include "service/machine_config.hpp"
#include "service/service.hpp"
#include "service/setpoint_file.hpp"
#include "service/whole_run.hpp"

namespace ncd::app {
namespace {

constexpr std::size_t kPlotBuckets = 1500;
constexpr double kMaxSimulatedS = 100.0 * 3600.0;  // a runaway guard: 100 h of motion

struct ReplayArgs {
  std::string path, machine, setpoints, report, plot, blocks;
  std::string start, tool_table;  // override the machine file's [program] start_mm, tool_table
  std::optional<double> chord_tolerance_mm;  // overrides [encoder] chord_tolerance_mm
  bool quiet = false;
  bool allow_interference = false;
  bool path_only = false;  // the path alone (no whole program around it)
};

// The NC program of --blocks: one block a line, LF, no `%` (the streamer frames it), written
// as it comes and renamed into place when the run succeeds.
class ProgramFile {
 public:
  explicit ProgramFile(const std::string& path) : file_(path, "--blocks", 1 << 16) {}
  void write(const std::string& block) {
    file_.write(block.data(), block.size());
    file_.write("\n", 1);
  }
  void commit() { file_.commit(); }

 private:
  StreamedFile file_;
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

// What replay records of every setpoint, as the service's loop drains it: the statistics, the
// setpoints file, the blocks and the plot, and the progress on standard error. The state lives
// in the run (the service destroys its sink when the job fails); the files are committed by
// the run once it has accepted the numbers, so commit() has nothing to do.
struct ReplayRecord {
  motion::JobConfig cfg;
  motion::RunStats st;
  PlotBuckets plot;
  double lookahead_ns = 0.0;  // sampling the limit curve for the planner, in total
  service::SetpointFileSink* file = nullptr;
  comms::ProgramBlocks* blocks = nullptr;  // --blocks; null without
  std::unique_ptr<motion::ToolUse> tools;  // the tool of each move, the law's caps
  bool quiet = false;
  double length_mm = 0.0;
  std::chrono::steady_clock::time_point next_progress;
  std::int64_t n = 0;
};

class ReplayRecorder final : public service::SetpointSink {
 public:
  explicit ReplayRecorder(ReplayRecord& r) : r_(r) {}
  void write(const motion::Setpoint& /*sp*/) override {
    throw InputError("replay: the job ran on a cycle thread; replay needs it on its own thread");
  }
  void write_period(const motion::Setpoint& sp, const motion::Job& job,
                    const motion::PeriodTimes& times) override {
    r_.lookahead_ns += static_cast<double>(times.prepare_ns);
    const double limit = job.limit_here().feed_mm_per_s;
    const double rough = job.roughness_here_um(sp.v_mm_per_s);
    motion::record(r_.st, r_.cfg, sp, limit, rough, static_cast<double>(times.step_ns));
    if (r_.tools) r_.tools->add(sp);
    r_.file->write(sp);
    if (r_.blocks) r_.blocks->push(sp);
    r_.plot.add(sp.t_s, sp.v_mm_per_s * 60.0, limit * 60.0, rough);
    if (sp.done) return;
    if (sp.t_s > kMaxSimulatedS) {
      // Unreachable by a valid input: check_estimate refused runs of more than a quarter of it.
      throw LimitError(
          "the motion did not finish within 100 h of simulated time, though it was "
          "estimated at most " +
          std::to_string(service::kMaxRunS / 3600.0) + " h: the walk crawls; nothing was written");
    }
    if (r_.quiet || (++r_.n & 1023) != 0) return;  // the clock read every 1024 periods
    const auto now = std::chrono::steady_clock::now();
    if (now > r_.next_progress) {
      std::cerr << "replay: " << static_cast<int>(100.0 * sp.s_mm / r_.length_mm) << " % ("
                << sp.t_s << " s simulated)\n";
      r_.next_progress = now + std::chrono::seconds(2);
    }
  }
  void commit() override {}

 private:
  ReplayRecord& r_;
};

Figure replay_figure(const PlotBuckets& plot, const PlotBuckets* blocks,
                     const service::MachineConfig& m, const std::string& source) {
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
  std::vector<Series> feeds{feed, limit};
  if (blocks) {
    Series written{"feed written in the blocks (F)", {}, {}, "#ff7f0e"};
    for (const auto& b : blocks->buckets()) {
      written.x.insert(written.x.end(), {b.t0_s, b.t1_s});
      written.y.insert(written.y.end(), {b.feed_max, b.feed_min});
    }
    feeds.push_back(std::move(written));
  }
  // The machine's maximum is drawn only when the feed comes near it; far above, it would flatten
  // the curves a reader looks at, so the title states it instead.
  double peak_mm_per_min = 0.0;
  for (const auto& b : plot.buckets()) peak_mm_per_min = std::max(peak_mm_per_min, b.feed_max);
  const double max_feed = m.limits.max_feed_mm_per_min;
  const bool show_max = peak_mm_per_min >= 0.25 * max_feed;
  char title[128];
  std::snprintf(title, sizeof title, "feed against time (machine maximum %.0f mm/min%s)", max_feed,
                show_max ? "" : ", off the scale");
  Panel p1{title, "feed (mm/min)", feeds, {}, {}};
  if (show_max) p1.lines.push_back({max_feed, "machine maximum feed"});
  Panel p2{"roughness predicted by the ball-end model (Choi)",
           "R_max (um)",
           {rough},
           {{m.cutting.roughness_target_um, "target"}},
           {{0.0, m.cutting.roughness_target_um, "within the target"}}};
  fig.panels = {p1, p2};
  return fig;
}

nlohmann::ordered_json report_json(const motion::RunStats& st, const service::MachineConfig& m,
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
  j["jerk_vector_max"] = st.jerk_vector_max_mm_per_s3;
  j["jerk_bound"] = motion::jerk_bound_in_force(m.limits.jerk_bound);
  if (m.limits.has_axis_limits()) j["axis_peaks"] = motion::axis_peaks_json(st, m.limits);
  if (m.limits.rotary.present()) j["rotary_axis"] = motion::rotary_json(st, m.limits);  // §3g
  // Corners under G64 P (docs/planner.md §3a, §3b): rounded by an arc, or passed without their
  // stop by overlapping the two moves; the deviation is the farthest overlapped setpoint's. The
  // setpoints then wait up to setpoint_delay_periods, within setpoint_delay_within_mm of a stop.
  const motion::OverlapReport& o = job.overlap_report();
  j["corners"] = {{"rounded", job.blend_report().corners},
                  {"rounded_max_deviation_mm", job.blend_report().max_deviation_mm},
                  {"overlapped", o.corners},
                  {"overlap_periods_saved", o.periods_saved},
                  {"overlap_max_deviation_mm", o.max_deviation_mm},
                  {"setpoint_delay_periods", job.delay_periods()},
                  {"setpoint_delay_within_mm", job.line_depth_within_mm()}};
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

// The encoder's lines of the summary.
void print_blocks(const comms::EncoderStats& b, const std::string& file) {
  std::fprintf(stderr,
               "  blocks            %lld (N%ld-N%ld), %lld chars, in %s; length min %.4f, "
               "median %.4f, max %.4f mm\n"
               "  link              %s, %.0f chars/s: use mean %.1f %%, peak %.1f %% (N%ld), "
               "overall %.1f %% (margin %.0f %%)\n"
               "  block chord error max %.5f mm (N%ld; tolerance %.5f mm, rounding %.5f mm)\n"
               "  controller model  %lld underruns (%.3f s), %lld waits at rest, buffer max "
               "%d of %d bytes\n",
               static_cast<long long>(b.blocks), b.first_number, b.last_number,
               static_cast<long long>(b.chars), file.c_str(), b.length_min_mm, b.length_median_mm(),
               b.length_max_mm, b.line.c_str(), b.chars_per_s, 100.0 * b.link_use_mean(),
               100.0 * b.link_use_peak, b.link_use_peak_block, 100.0 * b.link_use_overall(),
               100.0 * b.link_margin, b.chord_error_max_mm, b.chord_error_max_block,
               b.chord_tolerance_mm, b.rounding_error_mm, static_cast<long long>(b.queue.underruns),
               b.queue.underrun_time_s, static_cast<long long>(b.queue.waits_at_rest),
               b.queue.max_buffer_fill_bytes, b.rx_buffer_bytes);
  if (b.lowered_ranges == 0) {
    std::fprintf(stderr, "  feed lowered      nowhere: the link carries every block\n");
    return;
  }
  std::fprintf(stderr,
               "  feed lowered      in %lld blocks, %lld ranges (time %.3f s instead of %.3f s)\n",
               static_cast<long long>(b.lowered_blocks), static_cast<long long>(b.lowered_ranges),
               b.duration_s, b.planned_duration_s);
  constexpr std::size_t kShown = 5;
  for (std::size_t i = 0; i < std::min(kShown, b.lowered.size()); ++i) {
    const comms::LoweredRange& r = b.lowered[i];
    std::fprintf(stderr, "    N%ld-N%ld, s %.3f-%.3f mm: %.1f -> %.1f mm/min: %s\n", r.first_block,
                 r.last_block, r.s_from_mm, r.s_to_mm, r.planned_feed_mm_per_min,
                 r.lowered_feed_min_mm_per_min, r.reason.c_str());
  }
  if (b.lowered_ranges > static_cast<std::int64_t>(kShown)) {
    std::fprintf(stderr, "    ... (all of them in the report)\n");
  }
}

// What replay walks, read and checked before any motion: the machine, the path, the chamfer's
// checks and tool, the whole program around the path, its envelope and the size of the run.
struct ReplayInput {
  service::MachineConfig machine;  // the documented defaults unless --machine
  toolpath::Path path;
  service::ChamferAcceptance chamfer;
  service::WholeRun whole;
};

ReplayInput read_input(const ReplayArgs& a) {
  check_output(a.report, "--report");
  check_output(a.plot, "--plot");
  check_output(a.setpoints, "--setpoints");
  check_output(a.blocks, "--blocks");
  ReplayInput in;
  if (!a.machine.empty()) in.machine = service::load_machine_config(a.machine);
  if (a.chord_tolerance_mm) in.machine.encoder.chord_tolerance_mm = *a.chord_tolerance_mm;
  if (!a.start.empty())
    in.machine.program.start_machine_mm = service::parse_position_mm(a.start, "--start");
  if (!a.tool_table.empty()) in.machine.program.tool_table = a.tool_table;
  in.path = toolpath::read_path_file(a.path, in.machine.program);
  // Before any motion: the chamfer's checks and tool, the envelope, the size of the run.
  in.chamfer =
      service::accept_chamfer(in.path, in.machine, a.allow_interference, "--allow-interference");
  if (!in.chamfer.note.empty()) std::cerr << "replay: " << in.chamfer.note << "\n";
  in.whole = service::whole_run("ncd replay", a.path, in.path, in.machine, a.path_only);
  service::check_envelope(in.whole.path, in.machine);
  service::check_estimate(service::estimate_run(in.whole.path, in.machine), !a.setpoints.empty());
  return in;
}

// --blocks: the block encoder and the NC program it writes, with the feed it writes for the
// plot. Every written line is checked against the controller's dialect ([link] dialect) as it
// is written: a program the controller cannot take is refused (exit 2) and nothing is written.
// Not movable: the encoder's callback holds it.
struct BlockOutput {
  BlockOutput() = default;
  BlockOutput(const BlockOutput&) = delete;
  BlockOutput& operator=(const BlockOutput&) = delete;

  void check(const std::string& line) {
    ++written_lines;
    if (!dialect) return;
    if (auto v = comms::check_line(*dialect, line, dialect_state)) {
      v->line = written_lines;
      throw InputError("--blocks: the program breaks the machine's controller dialect: " +
                       comms::describe(*v, *dialect) + ". Nothing was written.");
    }
  }

  // Checks the encoder's settings (the dialect applied to them, in the machine too), opens the
  // program and starts its blocks with the whole program's header; before the walk starts.
  void open(const ReplayArgs& a, ReplayInput& in, const service::Service& svc) {
    service::MachineConfig& machine = in.machine;
    dialect = machine.link.dialect;
    try {
      comms::validate(machine.encoder);
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) +
                       " (--chord-tolerance or the machine file's [encoder])");
    }
    if (machine.link.dialect) comms::apply_dialect(machine.encoder, *machine.link.dialect);
    program = std::make_unique<ProgramFile>(a.blocks);
    if (in.chamfer.interference_allowed) {
      const std::string note =
          "(ncd: the chamfer failed its interference checks; written because of "
          "--allow-interference)";
      check(note);
      program->write(note);
    }
    encoder = std::make_unique<comms::BlockEncoder>(
        machine.encoder, [this](const comms::EncodedBlock& b) {
          check(b.text);
          program->write(b.text);
          if (b.positioning || b.feed_mm_per_min <= 0.0) return;
          plot.add(b.start_t_s, b.feed_mm_per_min, b.feed_mm_per_min, 0.0);
          plot.add(b.end_t_s, b.feed_mm_per_min, b.feed_mm_per_min, 0.0);
        });
    const motion::Job* built = svc.submitted_job();  // the events go where its segments start
    if (!built) throw std::logic_error("replay: the service holds no submitted job");
    blocks = std::make_unique<comms::ProgramBlocks>(in.whole.program, *encoder,
                                                    built->segment_starts_mm());
    if (!a.path_only) blocks->begin(in.whole.header);  // --path-only: the blocks alone
  }

  std::unique_ptr<ProgramFile> program;
  std::unique_ptr<comms::BlockEncoder> encoder;
  std::unique_ptr<comms::ProgramBlocks> blocks;
  PlotBuckets plot;  // the feed written in the blocks
  long written_lines = 0;
  comms::DialectState dialect_state;
  std::optional<comms::Dialect> dialect;
};

// The job, on the simulated clock and the owner's thread.
service::ServiceOptions replay_service_options() {
  service::ServiceOptions so;
  so.clock = motion::ClockKind::Simulated;
  so.realtime = false;
  so.cycle_thread = false;
  so.ring_capacity = 16;  // one setpoint in flight
  return so;
}

// Replay's acceptance rule judges the whole run from its statistics, so the live limit rules
// only count (Report).
service::JobSpec replay_job(const ReplayInput& in, ReplayRecord& rec) {
  service::JobSpec spec;
  spec.name = in.path.source;
  spec.path = std::make_shared<const toolpath::Path>(in.whole.path);
  spec.motion = rec.cfg;
  spec.rules = service::LiveLimitRules::from(rec.cfg.limits);
  spec.rules.feed = spec.rules.accel = spec.rules.jerk = spec.rules.chord =
      service::RuleAction::Report;
  spec.interference_allowed = in.chamfer.interference_allowed;
  spec.sink = std::make_unique<ReplayRecorder>(rec);
  return spec;
}

// How the run ended: the step rule's or the watchdog's fault, or the acceptance rule's refusal
// (empty: accepted), and the sampling time of the look-ahead.
struct RunEnd {
  std::string refused;
  double lookahead_ns = 0.0;
  double wall_s = 0.0;
};

// The report and the plot, written whether the run was accepted or not (to show why).
void write_report_and_plot(const ReplayArgs& a, const ReplayInput& in, const motion::Job& job,
                           const ReplayRecord& rec, const RunEnd& end, const BlockOutput& out) {
  const std::string& source = in.path.source;
  if (!a.report.empty()) {
    nlohmann::ordered_json report = report_json(rec.st, in.machine, source, job, end.lookahead_ns);
    if (rec.tools) report.update(rec.tools->to_json(job));  // tools, tool_runs, capped_moves
    report["accepted"] = end.refused.empty();
    report["interference_allowed"] = in.chamfer.interference_allowed;
    report["refused"] =
        end.refused.empty() ? nlohmann::ordered_json() : nlohmann::ordered_json(end.refused);
    if (out.encoder) {
      nlohmann::ordered_json blocks = {{"file", a.blocks}};
      blocks.update(comms::to_json(out.encoder->stats()));
      report["blocks"] = std::move(blocks);
    }
    write_output(a.report, report.dump(1) + "\n", "--report");
  }
  if (!a.plot.empty()) {
    write_output(
        a.plot,
        render_svg(replay_figure(rec.plot, out.encoder ? &out.plot : nullptr, in.machine, source)),
        "--plot");
  }
}

// The summary on standard error.
void print_summary(const ReplayArgs& a, const service::MachineConfig& machine,
                   const std::string& source, const motion::Job& job, const motion::RunStats& st,
                   double wall_s, const comms::BlockEncoder* encoder,
                   const motion::ToolUse* tools) {
  std::fprintf(stderr,
               "replay: %s\n  path length       %.4f mm in %lld periods of %.4g s = %.3f s\n"
               "  feed              max %.1f mm/min; roughness max %.3f um (target %.3f um)\n"
               "  feed error        max %.3g, rms %.3g (true arc against planned, steps >= 1 um);"
               " max %.3g mm\n"
               "  drift             %.3g mm; chord error max %.3g mm (tolerance %.3g mm)\n"
               "  accel, jerk max   %.1f mm/s2, %.0f mm/s3 (tangential); limit violations %lld\n"
               "  jerk vector max   %.0f mm/s3 (from the setpoints); bound in force: %s\n"
               "  corners (G64 P)   %zu rounded by arcs, %zu overlapped (%zu periods saved, "
               "%.4g mm from the corner at most)\n"
               "  step time         median %.0f ns, p99 %.0f ns; replayed in %.2f s "
               "(%.0f periods/s)\n",
               source.c_str(), st.path_length_mm, static_cast<long long>(st.cycles),
               machine.limits.period_s, st.duration_s, st.feed_max_mm_per_s * 60.0,
               st.roughness_max_um, machine.cutting.roughness_target_um, st.feed_error_max_rel,
               st.feed_error_rms_rel(), st.feed_error_max_abs_mm, st.drift_mm(),
               st.chord_error_max_mm, machine.limits.chord_tolerance_mm, st.accel_max_mm_per_s2,
               st.jerk_max_mm_per_s3, static_cast<long long>(st.limit_violations()),
               st.jerk_vector_max_mm_per_s3, motion::jerk_bound_in_force(machine.limits.jerk_bound),
               job.blend_report().corners, job.overlap_report().corners,
               job.overlap_report().periods_saved, job.overlap_report().max_deviation_mm,
               st.step_time_ns.quantile(0.5), st.step_time_ns.quantile(0.99), wall_s,
               static_cast<double>(st.cycles) / std::max(wall_s, 1e-9));
  std::fputs(motion::axis_peaks_text(st, machine.limits).c_str(), stderr);  // per-axis (§3f)
  std::fputs(motion::rotary_text(st, machine.limits).c_str(), stderr);      // rotary (§3g)
  if (tools) std::fputs(tools->text(job).c_str(), stderr);  // each tool, the law's caps
  if (job.delay_periods() > 0) {  // the corner overlap's line of setpoints (planner.md §3b)
    std::fprintf(stderr,
                 "  hold, override    act up to %zu periods (%.0f ms) late within %.1f mm of a "
                 "stop, for the corner overlap; elsewhere in the next period\n",
                 job.delay_periods(),
                 1e3 * machine.limits.period_s * static_cast<double>(job.delay_periods()),
                 job.line_depth_within_mm());
  }
  if (encoder) print_blocks(encoder->stats(), a.blocks);
}

int run_replay(const ReplayArgs& a) {
  ReplayInput in;
  try {
    in = read_input(a);
  } catch (const NoMotionError& e) {
    // Nothing to walk is an answer, not a failure; no output file is written.
    if (!a.quiet) std::cerr << "replay: no motion: " << e.what() << "\n";
    return 0;
  }
  ReplayRecord rec;
  rec.cfg.limits = in.machine.limits;
  rec.cfg.cutting = in.machine.cutting;
  rec.quiet = a.quiet;
  service::SetpointFileSink sink(a.setpoints, in.machine.limits.rotary.axis);
  rec.file = &sink;
  BlockOutput out;  // --blocks; checked before the walk starts
  service::Service svc(replay_service_options());
  svc.submit(replay_job(in, rec));  // builds the job once: a path the machine cannot run is refused
  rec.tools = std::make_unique<motion::ToolUse>(*svc.submitted_job());
  if (!a.blocks.empty()) {
    out.open(a, in, svc);
    rec.blocks = out.blocks.get();
  }
  const auto wall0 = std::chrono::steady_clock::now();
  rec.next_progress = wall0 + std::chrono::seconds(2);
  svc.start();  // the job and its first look-ahead window
  const motion::Job& job = *svc.job();
  rec.length_mm = job.length_mm();
  rec.st.path_length_mm = job.length_mm();
  const double r0 = job.path().rotary_start_deg;  // the rotary axis at rest before the first period
  rec.st.last_rotary_deg = {r0, r0, r0};
  rec.st.rotary_started = true;
  if (out.blocks) {
    // The start of the path, where the machine stands at rest before the first period.
    motion::Setpoint start;
    start.p = job.walker().position();
    out.blocks->push(start);
  }
  while (svc.poll()) {
  }
  const service::Status status = svc.status();
  RunEnd end;
  // The step rule (this setpoint is not emitted, the run ends there) or the no-progress
  // watchdog: the cycle's message.
  end.refused = status.state == service::State::Error ? status.error : std::string();
  end.lookahead_ns =
      rec.lookahead_ns +
      (svc.cycle_stats() ? static_cast<double>(svc.cycle_stats()->first_window_ns) : 0.0);
  end.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (out.blocks) out.blocks->end();
  // The acceptance rule: a run that stopped on the step rule, or whose numbers show a violation
  // or a drift, writes its report and plot (to show why) but no setpoints and no blocks.
  if (end.refused.empty()) end.refused = motion::refusal(rec.st, rec.cfg);
  write_report_and_plot(a, in, job, rec, end, out);
  if (!end.refused.empty()) {
    throw LimitError(in.path.source + ": " + end.refused +
                     "; no setpoints and no blocks were written (exit 3; the report and the plot "
                     "show the run)");
  }
  sink.commit();
  if (out.program) out.program->commit();
  if (!a.quiet) {
    print_summary(a, in.machine, in.path.source, job, rec.st, end.wall_s, out.encoder.get(),
                  rec.tools.get());
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
      "or an RS-274/NGC program, read as LinuxCNC reads it (docs/ngc-interpreter.md).");
  c->add_option("path", a->path, "path file")->required();
  c->add_option("--machine", a->machine,
                "machine file (TOML: period, limits, tolerances, [cutting]); default: the "
                "documented defaults, see config/machine.example.toml");
  c->add_option("--start", a->start,
                "X,Y,Z: where the machine stands when the program starts, machine mm (overrides "
                "the machine file's [program] start_mm); unset, a program must reach X, Y and Z "
                "with a rapid before its first feed move");
  c->add_option("--tool-table", a->tool_table,
                "LinuxCNC tool table, lines such as 'T1 P1 Z12.5 D6 ;ball' (overrides the "
                "machine file's [program] tool_table)");
  c->add_option("--setpoints", a->setpoints,
                "CSV of one row per period: t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit");
  c->add_option("--report", a->report, "JSON report of the run");
  c->add_option("--plot", a->plot,
                "SVG plot of feed and predicted roughness against time (with --blocks, also the "
                "feed written in the blocks)");
  c->add_option("--blocks", a->blocks,
                "NC program of the motion as a DNC link carries it: G1 blocks merged within the "
                "encoder's chord tolerance, fed within the [link] budget (one block a line, LF, "
                "no %); the report gains \"blocks\"");
  c->add_option("--chord-tolerance", a->chord_tolerance_mm,
                "block encoder chord tolerance, mm (default: the machine file's [encoder] "
                "chord_tolerance_mm, 0.002)");
  c->add_flag("--allow-interference", a->allow_interference,
              "walk a chamfer whose interference checks failed (a deliberate test cut); the "
              "summary, the report and the blocks say so");
  c->add_flag("--path-only", a->path_only,
              "walk and encode the path alone, without the whole program around it (preamble, "
              "tool, spindle, clearance plane, approach, retract, M5, M2)");
  c->add_flag("-q,--quiet", a->quiet, "no progress or summary on standard error");
  c->callback([a, &run] { run = [a] { return run_replay(*a); }; });
}

}  // namespace ncd::app
