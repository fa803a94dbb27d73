// `ncd sim-controller`: a simulated CNC controller on a pseudo-terminal linked at --link PATH,
// for `ncd stream` to send to. Runs until SIGTERM or SIGINT (or, with --exit-at-end, until the
// program end has been executed), then writes --log FILE.json and exits 0. SIGUSR1 is the
// cycle-start button: it resumes a program stopped by M0 (on the grbl link `~` does the same).
// The link path and the line come from the flags, else from the [link] of --machine FILE (its
// device is where the pty is linked), else the defaults (service/link_options.hpp).
#include <signal.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <random>

#include "app/commands.hpp"
#include "core/error.hpp"
#include "core/number_text.hpp"
#include "core/output_file.hpp"
#include "link/thread_priority.hpp"
#include "service/link_options.hpp"
#include "service/machine_config.hpp"
#include "sim/sim_controller.hpp"

namespace ncd::app {
namespace {

struct SimArgs {
  std::string link, log;
  service::LinkFlags flags;
  int buffer = 0;   // 0: 256 (drip) or 128 (ack, grbl)
  int xoff_at = 0;  // 0: default
  int xon_at = -1;  // -1: default
  int planner_blocks = 15;
  double rapid = 5000.0;
  bool exit_at_end = false;
  long long seed = -1;  // -1: random
  bool skip_duplicate_n = false, reset_on_open = false, report_line_numbers = false;
  double boot_s = 0.0;
  bool no_machine_safety = false, optional_stop = false;
  double tool_change_s = 5.0;
  int status_mask = 3;
  double accel = 100.0;
  comms::SimFaults faults;
};

// The controller a signal stops; set while run() runs. A stop or cycle start that arrives before
// (the pty link exists from the controller's construction, so a caller may signal at once) is
// held and delivered when the controller is attached.
std::atomic<comms::SimController*> g_running{nullptr};
std::atomic<bool> g_stop_pending{false};
std::atomic<bool> g_cycle_start_pending{false};

extern "C" void sim_controller_on_signal(int signal) {
  comms::SimController* c = g_running.load();
  if (signal == SIGUSR1) {
    if (c == nullptr) {
      g_cycle_start_pending.store(true);
    } else {
      c->cycle_start();
    }
  } else if (c == nullptr) {
    g_stop_pending.store(true);
  } else {
    c->request_stop();
  }
}

// SIGINT and SIGTERM stop the controller while this lives; the old handlers come back after.
// Installed before the controller (and its link) exists, so no signal finds the default action.
class StopSignals {
 public:
  StopSignals() {
    struct sigaction sa {};
    sa.sa_handler = sim_controller_on_signal;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGINT, &sa, &old_int_);
    ::sigaction(SIGTERM, &sa, &old_term_);
    ::sigaction(SIGUSR1, &sa, &old_usr1_);
  }
  // From here signals reach `c`; one held since construction is delivered now.
  void attach(comms::SimController& c) {
    g_running.store(&c);
    if (g_stop_pending.exchange(false)) c.request_stop();
    if (g_cycle_start_pending.exchange(false)) c.cycle_start();
  }
  // Signals no longer reach the controller (a later stop is held, and harmless).
  void detach() { g_running.store(nullptr); }
  ~StopSignals() {
    detach();
    ::sigaction(SIGINT, &old_int_, nullptr);
    ::sigaction(SIGTERM, &old_term_, nullptr);
    ::sigaction(SIGUSR1, &old_usr1_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
  struct sigaction old_usr1_ {};
};

// The link path, the line and the receive buffer: each from its flag, else from the machine
// file's [link] (--machine; its device is where the simulated controller's port appears), else
// the default (service/link_options.hpp). Prints where each value came from.
void choose_link(const SimArgs& a, comms::SimControllerConfig& cfg) {
  std::optional<service::MachineConfig> machine;
  if (!a.flags.machine.empty()) machine = service::load_machine_config(a.flags.machine);
  service::LinkSources src(a.flags, machine ? &*machine : nullptr);
  const service::LinkConfig file = machine ? machine->link : service::LinkConfig{};
  const std::string link = src.pick<std::string>(
      "--link", "device", a.link, file.line.device,
      [](const std::string& v) { return v.empty() ? std::string("none") : v; });
  cfg.line = src.line();
  cfg.line.device = link;
  cfg.dialect = src.dialect();
  cfg.buffer_bytes = src.pick<int>(
      "--buffer", "rx_buffer_bytes", a.buffer, file.rx_buffer_bytes,
      [](const int& v) { return v == 0 ? std::string("256, or 128 for ack") : std::to_string(v); });
  const std::string sender = "the sender's: ncd stream and ncd serve";
  for (const char* key : {"max_queued_chars", "xoff_timeout_s", "reconnect_max_s", "journal"}) {
    src.unused(key, sender);
  }
  if (link.empty()) {
    throw InputError("no link: give --link PATH (e.g. /tmp/cnc0)" +
                     std::string(machine ? ", or device = \"/tmp/cnc0\" in " + machine->source +
                                               " [link] (the port ncd stream opens)"
                                         : ", or --machine FILE whose [link] names the device"));
  }
  for (const std::string& l : src.report()) std::cerr << "ncd sim-controller: " << l << "\n";
}

int run_sim_controller(const SimArgs& a) {
  comms::SimControllerConfig cfg;
  choose_link(a, cfg);
  if (a.xoff_at != 0) cfg.xoff_at = a.xoff_at;
  if (a.xon_at != -1) cfg.xon_at = a.xon_at;
  cfg.planner_blocks = a.planner_blocks;
  cfg.rapid_mm_per_min = a.rapid;
  cfg.exit_at_end = a.exit_at_end;
  cfg.skip_duplicate_n = a.skip_duplicate_n;
  cfg.reset_on_open = a.reset_on_open;
  cfg.report_line_numbers = a.report_line_numbers;
  cfg.boot_s = a.boot_s;
  cfg.machine_safety = !a.no_machine_safety;
  cfg.tool_change_s = a.tool_change_s;
  cfg.optional_stop = a.optional_stop;
  cfg.status_mask = a.status_mask;
  cfg.hold_accel_mm_per_s2 = a.accel;
  if (a.seed < -1) {
    throw InputError("--seed " + std::to_string(a.seed) + " is invalid: use 0 or more");
  }
  cfg.seed = a.seed >= 0 ? static_cast<std::uint64_t>(a.seed) : std::random_device{}();
  cfg.faults = a.faults;
  cfg.on_event = [](const std::string& text) {
    std::cerr << "ncd sim-controller: " << text << std::endl;
  };
  if (!a.log.empty() && a.log != "-") {
    const std::filesystem::path dir = std::filesystem::path(a.log).parent_path();
    if (!dir.empty() && !std::filesystem::is_directory(dir)) {
      throw InputError("--log " + a.log + ": the folder " + dir.string() +
                       " does not exist; create it or choose another path");
    }
  }

  StopSignals signals;
  // A controller's serial reception is hard real time: SCHED_FIFO for the whole run, so that a
  // loaded host does not starve the simulated UART while the sender's wire model runs on.
  const comms::FifoPriority reception(cfg.fifo_priority);
  cfg.fifo_priority = 0;  // held here, for the banner to say it
  comms::SimController sim(cfg);
  const comms::SimControllerConfig& c = sim.config();
  std::cout << "ncd sim-controller: " << c.line.device << " -> " << sim.device() << ", "
            << describe(c.line) << " (" << text::fixed(comms::chars_per_s(c.line), 1)
            << " chars/s), buffer " << c.buffer_bytes << " B";
  if (c.line.protocol == comms::Protocol::Drip) {
    std::cout << ", XOFF at " << *c.xoff_at << ", XON at " << *c.xon_at;
  } else {
    std::cout << ", planner " << c.planner_blocks << " blocks";
  }
  std::cout << ", seed " << c.seed << "; reception at " << reception.description() << std::endl;
  signals.attach(sim);
  sim.run();
  signals.detach();
  const comms::SimLog& log = sim.log();
  std::cout << "ncd sim-controller: " << log.stop_reason << " after "
            << text::fixed(log.duration_s, 2) << " s: " << log.blocks_received << " blocks ("
            << log.bytes_received << " bytes at " << text::fixed(log.bytes_per_s, 0)
            << " B/s, link use " << text::fixed(log.link_use, 3) << "), underruns " << log.underruns
            << ", alarms " << log.alarms.size() << ", sha256 " << log.program_sha256 << std::endl;
  if (c.dialect) {
    std::cout << "ncd sim-controller: " << log.events.size() << " events executed ("
              << comms::to_string(*c.dialect) << " dialect)";
    for (const comms::SimEvent& e : log.events) {
      std::cout << (&e == &log.events.front() ? ": " : ", ") << e.kind;
      if (e.kind == "speed" || e.kind == "dwell" || e.kind == "tool") std::cout << " " << e.value;
      std::cout << " @" << text::fixed(e.t_s, 3) << " s";
    }
    std::cout << std::endl;
  }
  if (!a.log.empty()) write_output(a.log, comms::to_json(log).dump(2) + "\n");
  return 0;
}

}  // namespace

void register_sim_controller(CLI::App& app, Runner& run) {
  auto a = std::make_shared<SimArgs>();
  CLI::App* c = app.add_subcommand(
      "sim-controller",
      "A simulated CNC controller on a pseudo-terminal linked at --link PATH: paces reception at "
      "the line's speed, DC1/DC3 (drip) or grbl 1.1 (ack: ok when queued, 15-block planner, "
      "128-byte buffer, 79 characters a line, ? ! ~ and 0x18), executes the blocks in real time. "
      "Runs until SIGTERM/SIGINT (or --exit-at-end), then writes --log.");
  c->add_option("--link", a->link,
                "path of the symbolic link to the pty's slave, e.g. /tmp/cnc0 (default: the "
                "machine file's [link] device)");
  service::add_link_flags(*c, a->flags);
  c->add_option("--buffer", a->buffer,
                "receive buffer, bytes (64 … 1048576; default 256, or grbl's 128 with "
                "--protocol ack)");
  c->add_option("--xoff-at", a->xoff_at,
                "high-water mark: DC3 when the fill reaches it (default buffer − min(64, "
                "buffer/4))");
  c->add_option("--xon-at", a->xon_at,
                "low-water mark: DC1 when the fill falls to it (default xoff-at / 2)");
  c->add_option("--planner-blocks", a->planner_blocks,
                "ack: planner queue, blocks (the executing one included; grbl 1.1: 15)")
      ->capture_default_str();
  c->add_option("--rapid", a->rapid, "G0 rate, mm/min")->capture_default_str();
  c->add_option("--log", a->log, "write the run's log here (JSON, atomically) on exit");
  c->add_flag("--exit-at-end", a->exit_at_end,
              "exit once the program end has been executed (or 1 s after an alarm)");
  c->add_option("--seed", a->seed, "seed of the storm and noise faults (default: random)");
  c->add_flag("--skip-duplicate-n", a->skip_duplicate_n,
              "drip: discard a block whose N is not above the last one (a controller documented "
              "to skip repeated sequence numbers); without it a repeated block runs again");
  c->add_flag("--reset-on-open", a->reset_on_open,
              "ack: a sender opening the port resets the controller (an Arduino's DTR "
              "auto-reset): it boots for --boot-s, then sends its banner");
  c->add_option("--boot-s", a->boot_s,
                "ack: time from a reset to the banner; bytes received meanwhile are lost, s")
      ->capture_default_str();
  c->add_flag("--report-line-numbers", a->report_line_numbers,
              "ack: status reports carry Ln: (grbl built with USE_LINE_NUMBERS)");
  c->add_option("--status-mask", a->status_mask,
                "ack: grbl's $10 at start-up: 1 MPos (grbl's default), 2 WPos and Bf:, 3 MPos "
                "and Bf: (0 WPos); a $10=N line changes it")
      ->capture_default_str();
  c->add_option("--accel", a->accel,
                "ack: a feed hold's deceleration, mm/s² (grbl's $120): Hold:1 while slowing "
                "down, then Hold:0; a reset before Hold:0 is a reset in motion (ALARM:3)")
      ->capture_default_str();
  c->add_flag("--no-machine-safety", a->no_machine_safety,
              "with --dialect: no alarm for a feed move (G1 G2 G3) with the spindle stopped "
              "(grbl itself has no such check; the simulation's default is to alarm)");
  c->add_option("--tool-change-s", a->tool_change_s,
                "with --dialect iso or linuxcnc: an M6 tool change takes this long, s")
      ->capture_default_str();
  c->add_flag("--optional-stop", a->optional_stop,
              "M1 stops as M0 does (the operator's optional-stop switch on); grbl ignores M1");
  comms::SimFaults& f = a->faults;
  c->add_option("--drop-link-after-blocks", f.drop_link_after_blocks,
                "fault: link cut, the controller keeps running: after N blocks close the pty, "
                "remove the link, relink a new pty after --down-s");
  c->add_option("--drop-link-after-chars", f.drop_link_after_chars,
                "fault: the same cut in the middle of a line: after N characters of lines "
                "(real-time bytes and NULs not counted)");
  c->add_option("--reset-after-blocks", f.reset_after_blocks,
                "fault: controller reset after N blocks: the block executing is aborted, the "
                "buffers are lost, the position is kept, the banner is sent again (drip: DC3 "
                "SYN)");
  c->add_option("--restart-after-blocks", f.restart_after_blocks,
                "fault (ack): after N blocks the controller restarts as at power-up while its "
                "USB link goes down for --down-s: queue and modes lost, position restarts at 0, "
                "and its banner is sent while the port is closed (a sender never sees it)");
  c->add_option("--down-s", f.down_s, "fault: how long the link stays down, s")
      ->capture_default_str();
  c->add_flag("--xoff-storm", f.xoff_storm,
              "fault: random DC3, held 20–300 ms, then DC1, while receiving");
  c->add_option("--hold-after-blocks", f.hold_after_blocks,
                "fault: after N blocks hold the sender with DC3 for --hold-s");
  c->add_option("--hold-s", f.hold_s, "fault: length of the hold, s")->capture_default_str();
  c->add_option("--noise-bytes-per-s", f.noise_bytes_per_s,
                "fault: random bytes (drip) or garbage lines (ack) to the sender, bytes/s");
  c->add_option("--alarm-after-blocks", f.alarm_after_blocks,
                "fault: after N blocks raise an alarm (drip: DC3 NAK; ack: ALARM:9) and stop");
  c->callback([a, c, &run] {
    service::note_given_flags(*c, a->flags, {"--link", "--buffer"});
    run = [a] { return run_sim_controller(*a); };
  });
}

}  // namespace ncd::app
