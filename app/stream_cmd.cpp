// `ncd stream`: send an NC program to a controller over RS-232 DNC and exit 0 once the
// controller has all of it (drip: delivered; grbl: executed, as its status reports say). A
// transfer journal next to the program records the first block not known executed, so a
// stopped or killed transfer can resume there (--resume, drip with a controller that skips
// repeated N) or restart from any block with the modal state and a safe re-entry
// (--restart-from N). A job that does not complete ends with what to do next, as the flags to
// add to the same command ("next: … plus: --restart-from N"): for grbl the block comes from
// what its status reports said, and after ncd was killed from where grbl's position says it
// stopped. Exit status: 0 done, 2 invalid input, 3 the job did not complete (interrupted by a
// reset, an alarm, an error reply or a lost link, or stopped by a signal; the report names the
// blocks). docs/dnc-link.md has the rules. The port and the line settings come from the flags,
// else from the [link] of --machine FILE, else the defaults, and the command says which
// (service/link_options.hpp, LinkSources).
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "app/commands.hpp"
#include "core/error.hpp"
#include "core/number_text.hpp"
#include "core/output_file.hpp"
#include "gcode/dialect/program_modal.hpp"
#include "link/dnc_sender.hpp"
#include "link/program_file.hpp"
#include "link/transfer_journal.hpp"
#include "service/link_options.hpp"
#include "service/machine_config.hpp"

namespace ncd::app {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int /*signal*/) {
  g_stop.store(true);
}

struct StreamArgs {
  std::string program, port, journal, report;
  service::LinkFlags link;
  int max_queued_chars = 16;
  int rx_buffer_bytes = 128;
  double xoff_timeout_s = 5.0;
  double tool_change_s = 30.0;
  double reconnect_max_s = 30.0;
  bool resume = false, restart = false, no_journal = false, quiet = false;
  long restart_from = 0;  // 1-based block; 0: none
  std::optional<double> clearance_z_mm;
  int planner_blocks = 15;
  double status_hz = 5.0, banner_wait_s = 2.5, startup_timeout_s = 10.0;
  bool skips_repeated_n = false;
  bool unlock = false;
  // Chosen by choose_link: the controller's dialect (--dialect or the machine file's).
  std::optional<comms::Dialect> dialect;
  std::string port_from = "--port";  // the flag or key that gave the port, for messages
};

// The modal state in force before block `n` (1-based) and the highest Z reached before it.
comms::ModalState state_before(const std::string& path, long n, double& max_z_mm) {
  comms::ProgramFile src(path);
  comms::ProgramModal modal;
  std::string text;
  max_z_mm = -1e300;
  for (long k = 1; k < n && src.next(text) == comms::BlockStatus::Ready; ++k) {
    const comms::BlockMotion m = modal.apply(text);
    if (!m.known) {
      throw InputError("--restart-from " + std::to_string(n) + ": block " + std::to_string(k) +
                       " ('" + text +
                       "') moves in a way ncd does not follow (G28, G30, G53, "
                       "G92), so the position at block " +
                       std::to_string(n) + " is not known: restart from a block after it");
    }
    if (m.motion) max_z_mm = std::max(max_z_mm, m.to_mm[2]);
  }
  return modal.state();
}

// The restart flag for the first block not done (0-based), of `blocks`.
std::string restart_flag(std::int64_t first) {
  return first <= 0 ? "--restart" : "--restart-from " + std::to_string(first + 1);
}

// This command as it was typed (/proc/self/cmdline), without the flags that choose where a
// transfer starts (--resume, --restart, --restart-from N, --controller-skips-repeated-n,
// --unlock), each argument quoted for the shell where it needs it.
std::string command_without_start_flags() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::vector<std::string> args;
  for (std::string a; std::getline(in, a, '\0');) args.push_back(a);
  if (args.empty()) args = {"ncd", "stream"};
  std::string out;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--resume" || a == "--restart" || a == "--controller-skips-repeated-n" ||
        a == "--unlock" || a.rfind("--restart-from=", 0) == 0) {
      continue;
    }
    if (a == "--restart-from") {
      ++i;  // and its number
      continue;
    }
    const bool plain = !a.empty() && a.find_first_not_of(
                                         "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLM"
                                         "NOPQRSTUVWXYZ0123456789_./=:,+-@%") == std::string::npos;
    std::string quoted = "'";
    for (char c : a) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    out += (out.empty() ? "" : " ") + (plain ? a : quoted + "'");
  }
  return out;
}

// The advice's flags after "plus: ", and on the next line the whole command to run.
std::string plus(const std::string& flags) {
  return "plus: " + flags + "\nrun: " + command_without_start_flags() + " " + flags;
}

// What to do after a job that did not complete: why, what to check, and the flags to add to the
// same command after "plus: ", then the command itself after "run: " on the next line.
std::string next_step(const comms::SenderReport& r, bool ack, bool skips_repeated_n, bool journal,
                      std::int64_t program_blocks) {
  const std::int64_t first = r.blocks_confirmed;
  if (first >= program_blocks) return "every block has run: nothing is left to send";
  if (!ack) {
    if (skips_repeated_n && journal) {
      return "check the machine, then send the rest with the same port settings " +
             plus("--resume --controller-skips-repeated-n");
    }
    if (r.stopped && r.cut_block < 0 && r.interrupted == false) {
      return "every block written reached the line: the controller has blocks up to " +
             std::to_string(first) +
             " and runs them, and nothing after; check the machine (it stops at the end of "
             "block " +
             std::to_string(first) + "), then send the rest with the same port settings " +
             plus(restart_flag(first));
    }
    return "a drip-feed controller runs what it receives and says nothing: it may have run "
           "blocks up to " +
           std::to_string(first) + " (the first not sent is " + std::to_string(first + 1) +
           "); check the machine: if it stopped earlier, use its first block not run instead of " +
           std::to_string(first + 1) +
           (r.cut_block >= 0 ? ", and clear its input first (it holds part of block " +
                                   std::to_string(r.cut_block + 1) + ")"
                             : std::string()) +
           "; then send the rest with the same port settings " + plus(restart_flag(first));
  }
  const comms::HaltReport& h = r.halt;
  std::string s;
  if (h.attempted && !h.at_rest) {
    s = "the controller could not be brought to a safe halt (" + h.detail + "); ";
  }
  if (r.rejected_block >= 0) {
    s += "fix block " + std::to_string(r.rejected_block + 1) + " (the controller refused it), ";
  }
  if (r.blocks_executed < 0) {
    return s + "check the machine: executed blocks are not known without status reports, and " +
           std::to_string(first + 1) +
           " is the first not queued; if it stopped earlier, use its first block not run "
           "instead; then send the rest with the same port settings " +
           plus(restart_flag(first));
  }
  const bool alarm = r.controller_state == "Alarm";
  if (alarm || r.position_may_be_lost) {
    s += "check the machine: its position may be lost (" +
         std::string(alarm ? "grbl is in alarm, locked until $X; " : "the controller reset; ") +
         "home it ($H) if it has homing switches, or set its zero again)";
  } else {
    s += "check the machine";
  }
  return s + ", then send the rest with the same port settings " +
         plus((alarm ? "--unlock " : "") + restart_flag(first));
}

// A grbl transfer that stopped without finishing (ncd was killed): grbl ran on through the
// blocks it had queued, so the journal's block is behind the machine. Where grbl stands now
// (asked with `?` only) says which block is the first not done; the refusal names it.
std::string advice_after_stop(const comms::SenderSettings& settings, const std::string& program,
                              const comms::JournalState& j, const std::string& journal_path) {
  std::string head = "a transfer of " + program + " to grbl stopped before the end (journal " +
                     journal_path + ": its first block not known executed is " +
                     std::to_string(j.confirmed + 1) + " of " + std::to_string(j.blocks) +
                     "), and grbl ran on through the blocks it had queued, so --resume cannot be "
                     "used";
  const std::string fallback =
      "; check the machine: " + std::to_string(j.confirmed + 1) +
      " is the journal's first block not known executed, and grbl may have run past it: if it "
      "did, use its first block not run instead; then send the rest with the same port "
      "settings " +
      plus(restart_flag(j.confirmed));
  const comms::GrblProbe p = comms::probe_grbl(settings, 60.0);
  if (!p.spoke)
    return head + "; where grbl stands could not be read (" + p.failure + ")" + fallback;
  if (p.banner) {
    return head + "; grbl reset when the port opened, so its position tells nothing" + fallback;
  }
  if (p.state == "Run" || p.state == "Jog" || p.state == "Hold:1") {
    return head + "; grbl is still moving (" + p.state +
           ") after 60 s: wait until it is Idle, "
           "then run this again";
  }
  if (!p.position) {
    return head + "; grbl reports its machine position without the work offset (WCO)" + fallback;
  }
  const auto& x = *p.position;
  const std::string at =
      text::fixed(x[0], 3) + ", " + text::fixed(x[1], 3) + ", " + text::fixed(x[2], 3);
  const comms::PositionMatch m = comms::match_position(program, j.confirmed, j.sent_bound, x);
  if (!m.first_not_done) {
    return head + "; grbl is " + p.state + " at " + at + ", and " + m.why + fallback;
  }
  const std::int64_t first = *m.first_not_done;
  if (first >= j.blocks) {
    return head + "; grbl is " + p.state + " at " + at +
           ", the end of the last move: every block has run (to send it all again: " +
           plus("--restart") + ")";
  }
  const bool alarm = p.state == "Alarm";
  return head + "; grbl is " + p.state + " at " + at + ", " +
         (m.at_end ? "the end of block " : "inside block ") + std::to_string(m.move + 1) +
         ", the only block sent that it lies on: check the machine" +
         (alarm ? " (grbl is in alarm, locked until $X: its position may be lost)" : "") +
         ", then send the rest with the same port settings " +
         plus((alarm ? "--unlock " : "") + restart_flag(first));
}

nlohmann::json report_json(const comms::SenderReport& r, const comms::LineSettings& line,
                           const std::string& program, const comms::ProgramSummary& sum,
                           const std::string& journal) {
  return {
      {"program", program},
      {"program_summary",
       {{"path", program}, {"blocks", sum.blocks}, {"bytes", sum.bytes}, {"sha256", sum.sha256}}},
      {"transfer",
       {{"first_block", r.first_block + 1},
        {"blocks_sent", r.blocks_sent},
        {"blocks_queued", line.protocol == comms::Protocol::Ack ? nlohmann::json(r.blocks_queued)
                                                                : nlohmann::json(nullptr)},
        {"blocks_executed",
         r.blocks_executed >= 0 ? nlohmann::json(r.blocks_executed) : nlohmann::json(nullptr)},
        {"execution_basis", r.execution_basis},
        // Drip knows no executed block; the journal's point is then the first block not
        // sent (carried by the line): whether the blocks before it arrived is not known.
        {"first_block_not_known_executed",
         r.blocks_executed >= 0 ? r.blocks_confirmed + 1 : r.first_block + 1},
        {"first_block_not_sent",
         r.blocks_executed >= 0 ? nlohmann::json(nullptr) : nlohmann::json(r.blocks_confirmed + 1)},
        {"interrupted", r.interrupted},
        {"dropped", r.dropped},
        {"rejected_block",
         r.rejected_block >= 0 ? nlohmann::json(r.rejected_block + 1) : nlohmann::json(nullptr)},
        {"controller_state", r.controller_state},
        {"halt",
         {{"attempted", r.halt.attempted},
          {"at_rest", r.halt.at_rest},
          {"reset", r.halt.reset},
          {"alarm", r.halt.alarm},
          {"rest_s", r.halt.rest_s},
          {"state", r.halt.state},
          {"detail", r.halt.detail}}},
        {"reconnects", r.reconnects},
        {"link_losses", r.link_losses},
        {"startup", r.startup},
        {"bytes_before_banner", r.bytes_before_banner},
        {"status_reports", r.status_reports},
        {"notes", r.notes}}},
      {"port", line.device},
      {"settings", comms::describe(line)},
      {"chars_per_s", comms::chars_per_s(line)},
      {"completed", r.completed},
      {"stopped", r.stopped},
      {"failure", r.failure},
      {"first_block", r.first_block},
      {"blocks", r.blocks},
      {"blocks_confirmed", r.blocks_confirmed},
      {"blocks_resent", r.blocks_resent},
      {"bytes_written", r.bytes_written},
      {"bytes_in_flight", r.bytes_in_flight},
      {"controller_silent", r.controller_silent},
      {"cut_block", r.cut_block >= 0 ? nlohmann::json(r.cut_block + 1) : nlohmann::json(nullptr)},
      {"holds_explained", r.holds_explained},
      {"program_bytes", r.program_bytes},
      {"program_sha256", r.program_sha256},
      {"duration_s", r.duration_s},
      {"link_use", r.link_use},
      {"scheduling", r.scheduling},
      {"xoff_count", r.xoff_count},
      {"xoff_total_s", r.xoff_total_s},
      {"xoff_longest_s", r.xoff_longest_s},
      {"xoff_timeouts", r.xoff_timeouts},
      {"reconnects", r.reconnects},
      {"noise_bytes", r.noise_bytes},
      {"alarms", r.alarms},
      {"max_output_queue", r.max_output_queue},
      {"max_queued_estimate", r.max_queued_estimate},
      {"max_unacked_bytes", r.max_unacked_bytes},
      {"journal", journal}};
}

// The flags alone, before the program is read.
void check_flags(const StreamArgs& a, const comms::LineSettings& line) {
  require_positive("--xoff-timeout (s)", a.xoff_timeout_s);
  require_positive("--tool-change-s (s)", a.tool_change_s);
  require_positive("--reconnect-max (s)", a.reconnect_max_s);
  if (a.max_queued_chars < 1 || a.max_queued_chars > 4096) {
    throw InputError("--max-queued " + std::to_string(a.max_queued_chars) +
                     " is out of range: use 1 to 4096 characters (a controller stops the "
                     "sender within a few; 16 is safe for a 256-byte buffer)");
  }
  if (a.rx_buffer_bytes < 16 || a.rx_buffer_bytes > 65536) {
    throw InputError("--rx-buffer " + std::to_string(a.rx_buffer_bytes) +
                     " is out of range: use the controller's receive buffer, 16 to 65536 bytes "
                     "(grbl 128, grblHAL 1024)");
  }
  if (a.resume && a.restart) throw InputError("--resume and --restart exclude each other");
  if (a.restart_from != 0 && (a.resume || a.restart)) {
    throw InputError("--restart-from excludes --resume and --restart: it starts a new transfer");
  }
  if (line.protocol == comms::Protocol::Ack && line.eob == comms::EndOfBlock::CrLf) {
    throw InputError(
        "--eob crlf with --protocol ack: grbl ends a line at CR and at LF, so CR LF "
        "is a block and an empty line, answered by two oks, and character "
        "counting would lose count; use --eob lf");
  }
  if (a.status_hz < 0.0 || a.status_hz > 10.0) {
    throw InputError("--status-hz " + text::fixed(a.status_hz, 2) +
                     " is out of range: use 0 (no polling) or up to 10 (grbl: 5 to 10)");
  }
  if (a.planner_blocks < 1 || a.planner_blocks > 1000) {
    throw InputError("--planner-blocks " + std::to_string(a.planner_blocks) +
                     " is out of range: use 1 to 1000 (grbl 1.1: 15)");
  }
  require_positive("--banner-wait (s)", a.banner_wait_s);
  require_positive("--startup-timeout (s)", a.startup_timeout_s);
}

// The program, read once before the port is opened, and the controller's dialect.
struct CheckedProgram {
  comms::ProgramSummary summary;
  std::optional<comms::Dialect> dialect;
};

// The program's blocks against the dialect, the longest block grbl keeps and the range of
// --restart-from. Nothing is sent when it fails.
CheckedProgram check_program(const StreamArgs& a, const comms::LineSettings& line) {
  const bool ack = line.protocol == comms::Protocol::Ack;
  const int max_block = ack ? a.rx_buffer_bytes - 2 : 4096;
  CheckedProgram out;
  out.summary = comms::scan_program(a.program, line.data_bits, max_block);
  const comms::ProgramSummary& program = out.summary;
  out.dialect = a.dialect;
  const std::optional<comms::Dialect>& dialect = out.dialect;
  if (dialect) {  // before the port is opened: nothing is sent
    if (const auto v = comms::check_program_file(a.program, *dialect)) {
      throw InputError(a.program + ": " + comms::describe(*v, *dialect) + "; nothing was sent");
    }
  }
  if (ack && program.longest_kept > comms::kGrblLineChars) {
    throw InputError(a.program + ":" + std::to_string(program.longest_kept_line) + ": a block of " +
                     std::to_string(program.longest_kept) +
                     " characters without spaces and comments; grbl keeps " +
                     std::to_string(comms::kGrblLineChars) +
                     " and answers error:11: split the block or shorten its numbers");
  }
  if (a.restart_from < 0 || a.restart_from > program.blocks) {
    throw InputError("--restart-from " + std::to_string(a.restart_from) +
                     " is out of range: the program has blocks 1 to " +
                     std::to_string(program.blocks));
  }
  return out;
}

// --restart-from N: the blocks that bring the machine to N's start (the modal state in force
// at N, up to the clearance plane, over N's start, down at feed); none without it.
std::vector<std::string> restart_preamble(const StreamArgs& a,
                                          const std::optional<comms::Dialect>& dialect) {
  if (a.restart_from <= 0) return {};
  double max_z = 0.0;
  const comms::ModalState at = state_before(a.program, a.restart_from, max_z);
  double clearance = 0.0;
  if (a.clearance_z_mm) {
    clearance = *a.clearance_z_mm;
  } else if (max_z > -1e299) {
    clearance = max_z;
  } else {
    throw InputError("--restart-from " + std::to_string(a.restart_from) +
                     ": no move before it says where the clearance plane is: give "
                     "--clearance-z MM (work coordinates)");
  }
  if (clearance < at.position_mm[2]) {
    throw InputError("--clearance-z " + text::fixed(clearance, 3) + " is below block " +
                     std::to_string(a.restart_from) + "'s start at Z " +
                     text::fixed(at.position_mm[2], 3) + ": give a clearance plane above the part");
  }
  return comms::restart_blocks(at, clearance, dialect);
}

// An unfinished transfer in the journal: refused with what to do, or (--resume on a drip link
// whose controller skips repeated N) the block to resume at.
std::int64_t resume_block(const StreamArgs& a, const comms::LineSettings& line,
                          const comms::JournalState& previous, const std::string& journal_path,
                          const std::string& sha256) {
  if (previous.program_sha256 != sha256) {
    throw InputError("the journal " + journal_path +
                     " belongs to a different program (its checksum differs): pass "
                     "--restart to send this program from the start, or --journal FILE");
  }
  // grbl, with or without --resume: where it stands says where to restart.
  if (line.protocol == comms::Protocol::Ack) {
    comms::SenderSettings probe;
    probe.line = line;
    probe.banner_wait_s = a.banner_wait_s;
    throw InputError(advice_after_stop(probe, a.program, previous, journal_path));
  }
  // Without --controller-skips-repeated-n one advice, with or without --resume: the restart
  // from the journal's block, which a drip controller cannot run twice.
  const std::string restart_advice =
      "check the machine: if it stopped before the end of block " +
      std::to_string(previous.confirmed) + ", use its first block not run instead of " +
      std::to_string(previous.confirmed + 1) + "; then send the rest with the same port settings " +
      plus(restart_flag(previous.confirmed)) +
      "\n(to send it all again: --restart; --resume only for a controller whose manual says it "
      "discards repeated N numbers, with --controller-skips-repeated-n)";
  if (a.resume && !a.skips_repeated_n) {
    throw InputError("--resume on a drip-feed link: the journal's block " +
                     std::to_string(previous.confirmed + 1) +
                     " is the first the controller surely lacks, but it may have received more, "
                     "and it would run them twice; " +
                     restart_advice);
  }
  if (!a.resume) {
    throw InputError("a transfer of " + a.program + " stopped at block " +
                     std::to_string(previous.confirmed + 1) + " of " +
                     std::to_string(previous.blocks) + " (journal " + journal_path + "): " +
                     (a.skips_repeated_n
                          ? "check the machine, then continue there " +
                                plus("--resume --controller-skips-repeated-n")
                          : "a drip-feed controller may have received blocks after it and runs a "
                            "block it receives twice; " +
                                restart_advice));
  }
  if (previous.settings != comms::describe(line)) {
    std::cerr << "ncd stream: warning: the journal was written at " << previous.settings << ", now "
              << comms::describe(line) << "\n";
  }
  return previous.confirmed;
}

// The first block to send (0-based): --restart-from's, or where a previous transfer of the
// same program stopped (its journal), or the first.
std::int64_t first_block_to_send(const StreamArgs& a, const comms::LineSettings& line,
                                 const std::string& journal_path, const std::string& sha256) {
  const std::int64_t first_block = a.restart_from > 0 ? a.restart_from - 1 : 0;
  if (journal_path.empty() || a.restart || a.restart_from != 0) return first_block;
  const auto previous = comms::TransferJournal::read(journal_path);
  if (previous && !previous->complete)
    return resume_block(a, line, *previous, journal_path, sha256);
  if (a.resume) {
    throw InputError("--resume: there is no unfinished transfer in " + journal_path +
                     "; run without --resume to send the program");
  }
  return first_block;
}

comms::SenderSettings sender_settings(const StreamArgs& a, const comms::LineSettings& line,
                                      const std::vector<std::string>& preamble,
                                      const std::optional<comms::Dialect>& dialect) {
  comms::SenderSettings settings;
  settings.line = line;
  settings.max_queued_chars = a.max_queued_chars;
  settings.rx_buffer_bytes = a.rx_buffer_bytes;
  settings.xoff_timeout_s = a.xoff_timeout_s;
  settings.tool_change_s = a.tool_change_s;
  settings.reconnect_max_s = a.reconnect_max_s;
  settings.planner_blocks = a.planner_blocks;
  settings.status_hz = a.status_hz;
  settings.banner_wait_s = a.banner_wait_s;
  settings.startup_timeout_s = a.startup_timeout_s;
  settings.controller_skips_repeated_n = a.skips_repeated_n;
  settings.preamble = preamble;
  settings.dialect = dialect;
  // Ctrl-C: hold grbl, reset it once at rest (docs/dnc-link.md)
  settings.halt_on_stop = line.protocol == comms::Protocol::Ack;
  settings.unlock = a.unlock;
  return settings;
}

void print_start(const StreamArgs& a, const comms::LineSettings& line,
                 const comms::ProgramSummary& program, std::int64_t first_block,
                 const std::vector<std::string>& preamble) {
  std::cerr << "ncd stream: " << a.program << ": " << program.blocks << " blocks, " << program.bytes
            << " bytes, sha256 " << program.sha256 << "\n"
            << "ncd stream: " << comms::describe(line) << " carries "
            << text::fixed(comms::chars_per_s(line), 0) << " characters/s; at least "
            << text::fixed(static_cast<double>(program.bytes) / comms::chars_per_s(line), 1)
            << " s on the wire"
            << (first_block > 0 ? "; resuming at block " + std::to_string(first_block + 1) : "")
            << std::endl;
  for (const std::string& p : preamble) std::cerr << "ncd stream: restart: " << p << "\n";
}

void catch_stop_signals() {
  g_stop.store(false);
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

// The program, then the transfer: what was sent, queued, executed.
void print_transfer(const comms::SenderReport& r, const comms::ProgramSummary& program, bool ack) {
  std::cout << "program: " << program.blocks << " blocks, " << program.bytes << " bytes, sha256 "
            << program.sha256 << "\n";
  std::cout << (r.completed ? "done: "
                : r.stopped ? "STOPPED: "
                            : "INTERRUPTED: ")
            << "from block " << r.first_block + 1 << ", " << r.blocks_sent << " blocks sent";
  if (ack) std::cout << ", " << r.blocks_queued << " queued (ok)";
  if (r.blocks_executed >= 0) {
    std::cout << ", " << r.blocks_executed << " executed (by " << r.execution_basis << ")";
  } else {
    std::cout << "; executed blocks not known (" << r.execution_basis << ")";
  }
  std::cout << "; " << r.bytes_written << " bytes in " << text::fixed(r.duration_s, 2) << " s, "
            << text::fixed(100.0 * r.link_use, 1) << " % of the line; XOFF " << r.xoff_count
            << " times (longest " << text::fixed(r.xoff_longest_s, 2) << " s), " << r.link_losses
            << " link losses, " << r.reconnects << " resumed, " << r.blocks_resent
            << " blocks resent, " << r.noise_bytes << " noise bytes ignored\n";
  for (const std::string& n : r.notes) std::cout << "note: " << n << "\n";
}

// Every block went out but nothing ever came back: exit 4 (docs/cmd-stream.md, "Nothing
// answered").
int warn_silent(const StreamArgs& a, const comms::SenderReport& r) {
  const std::string w =
      "WARNING: nothing ever answered on " + a.port +
      (a.link.given.count("--port") == 0 ? " (" + a.port_from + ")" : std::string()) +
      ": no DC1/DC3, no byte at all" +
      "; check the cable and that the controller is in DNC/receive mode; the " +
      std::to_string(r.blocks_sent) + " blocks sent may not have arrived (exit 4)";
  std::cout << w << "\n";
  std::cerr << "ncd stream: " << w << "\n";
  return 4;
}

// A transfer that did not complete: where it stopped, why, and what to do next.
void print_unfinished(const StreamArgs& a, const comms::SenderReport& r, bool ack, bool journal,
                      std::int64_t program_blocks) {
  if (r.stopped) {
    std::cout << "stopped; the first block not known " << (ack ? "executed" : "sent") << " is "
              << r.blocks_confirmed + 1 << "\n";
  } else {
    std::cout << "interrupted: " << r.failure << "\n";
  }
  if (!r.dropped.empty()) std::cout << "dropped: " << r.dropped << "\n";
  if (ack && !r.controller_state.empty()) {
    std::cout << "controller: " << r.controller_state << "\n";
  }
  const std::string next = next_step(r, ack, a.skips_repeated_n, journal, program_blocks);
  if (!next.empty()) std::cout << "next: " << next << "\n";
}

// The port, the line and the sender's settings: each from its flag, else from the machine file's
// [link] (--machine), else the default (service/link_options.hpp). Sets them in `a`; returns
// the line and prints where each value came from unless --quiet.
comms::LineSettings choose_link(StreamArgs& a) {
  std::optional<service::MachineConfig> machine;
  if (!a.link.machine.empty()) machine = service::load_machine_config(a.link.machine);
  service::LinkSources src(a.link, machine ? &*machine : nullptr);
  const service::LinkConfig file = machine ? machine->link : service::LinkConfig{};
  const auto word = [](const std::string& v) { return v.empty() ? std::string("none") : v; };
  const auto number = [](const int& v) { return std::to_string(v); };
  const auto seconds = [](const double& v) { return text::sig(v) + " s"; };
  a.port = src.pick<std::string>("--port", "device", a.port, file.line.device, word);
  comms::LineSettings line = src.line();
  line.device = a.port;
  if (machine && a.link.given.count("--port") == 0) {
    a.port_from = "device in " + machine->source + " [link]";
  }
  a.dialect = src.dialect();
  a.rx_buffer_bytes = src.pick<int>("--rx-buffer", "rx_buffer_bytes", a.rx_buffer_bytes,
                                    file.rx_buffer_bytes, number);
  a.max_queued_chars = src.pick<int>("--max-queued", "max_queued_chars", a.max_queued_chars,
                                     file.max_queued_chars, number);
  a.xoff_timeout_s = src.pick<double>("--xoff-timeout", "xoff_timeout_s", a.xoff_timeout_s,
                                      file.xoff_timeout_s, seconds);
  a.reconnect_max_s = src.pick<double>("--reconnect-max", "reconnect_max_s", a.reconnect_max_s,
                                       file.reconnect_max_s, seconds);
  src.unused("journal",
             "the service's journal of a live job; ncd stream keeps one per program, "
             "PROGRAM.journal, or --journal FILE");
  if (a.port.empty()) {
    throw InputError(
        "no port: give --port DEVICE (e.g. /dev/ttyS0)" +
        std::string(machine ? ", or device = \"/dev/ttyS0\" in " + machine->source + " [link]"
                            : ", or --machine FILE whose [link] names the device"));
  }
  if (!a.quiet) {
    for (const std::string& l : src.report()) std::cerr << "ncd stream: " << l << "\n";
  }
  return line;
}

int run_stream(const StreamArgs& given) {
  StreamArgs args = given;
  const comms::LineSettings line = choose_link(args);
  const StreamArgs& a = args;
  check_flags(a, line);
  const bool ack = line.protocol == comms::Protocol::Ack;
  const CheckedProgram checked = check_program(a, line);
  const comms::ProgramSummary& program = checked.summary;
  const std::vector<std::string> preamble = restart_preamble(a, checked.dialect);
  service::require_serial_port(a.port,
                               a.port_from);  // a file or a missing port: exit 2 now, no retries

  // The journal: resume where a previous transfer of the same program stopped.
  const std::string journal_path =
      a.no_journal ? "" : (a.journal.empty() ? a.program + ".journal" : a.journal);
  const std::int64_t first_block = first_block_to_send(a, line, journal_path, program.sha256);
  std::unique_ptr<comms::TransferJournal> journal;
  if (!journal_path.empty()) {
    comms::JournalState start;
    start.program_sha256 = program.sha256;
    start.settings = comms::describe(line);
    start.blocks = program.blocks;
    start.confirmed = first_block;
    journal = std::make_unique<comms::TransferJournal>(journal_path, start);
  }

  comms::ProgramFile source(a.program);
  const bool quiet = a.quiet;
  comms::DncSender sender(sender_settings(a, line, preamble, checked.dialect), source,
                          [quiet](const comms::SenderEvent& e) {
                            if (quiet && e.kind == comms::SenderEvent::Kind::Progress) return;
                            std::cerr << "ncd stream: [" << text::fixed(e.t_s, 3) << " s] "
                                      << e.text << std::endl;
                          });
  sender.set_journal(journal.get());
  sender.resume_from(first_block);
  if (!quiet) print_start(a, line, program, first_block, preamble);
  catch_stop_signals();
  const comms::SenderReport r = sender.run(g_stop);
  if (!quiet) std::cerr << "ncd stream: the sending thread ran at " << r.scheduling << "\n";

  if (!a.report.empty()) {
    write_output(a.report, report_json(r, line, a.program, program, journal_path).dump(2) + "\n");
  }
  print_transfer(r, program, ack);
  if (r.completed) {
    if (!journal_path.empty()) std::filesystem::remove(journal_path);
    if (r.controller_silent) return warn_silent(a, r);
    return 0;
  }
  print_unfinished(a, r, ack, !journal_path.empty(), program.blocks);
  return 3;
}

}  // namespace

void register_stream(CLI::App& app, Runner& run) {
  auto a = std::make_shared<StreamArgs>();
  CLI::App* c = app.add_subcommand(
      "stream",
      "Send an NC program to a controller over RS-232 DNC (drip feed with XON/XOFF or RTS/CTS, "
      "or grbl-type acknowledged streaming). Exits 0 once the controller has all of it, 3 if "
      "the transfer stopped, with what to do next (a restart from the first block not known "
      "executed, as a command to run), 4 if every block went out but nothing ever answered on "
      "the line.");
  c->add_option("program", a->program, "the NC program (one block per line)")->required();
  c->add_option("--port", a->port,
                "serial device, e.g. /dev/ttyS0 or a sim-controller link (default: the machine "
                "file's [link] device)");
  service::add_link_flags(*c, a->link);
  c->add_option("--max-queued", a->max_queued_chars,
                "drip: characters allowed ahead of the wire, i.e. how far the sender runs on "
                "after a DC3")
      ->capture_default_str();
  c->add_option("--rx-buffer", a->rx_buffer_bytes,
                "ack: the controller's receive buffer in bytes, for character counting")
      ->capture_default_str();
  c->add_option("--xoff-timeout", a->xoff_timeout_s,
                "report a hold (XOFF or CTS low) longer than this, in s")
      ->capture_default_str();
  c->add_option("--tool-change-s", a->tool_change_s,
                "the longest a tool change (M6) holds the line, s: a hold while one may run is "
                "allowed this on top of --xoff-timeout")
      ->capture_default_str();
  c->add_option("--reconnect-max", a->reconnect_max_s,
                "keep reopening a lost port for this long, in s")
      ->capture_default_str();
  c->add_option("--journal", a->journal, "transfer journal (default PROGRAM.journal)");
  c->add_flag("--no-journal", a->no_journal, "keep no journal");
  c->add_flag("--resume", a->resume, "continue an unfinished transfer from its journal");
  c->add_flag("--restart", a->restart, "ignore an unfinished transfer and send it all");
  c->add_option("--report", a->report, "write the transfer report as JSON to this file");
  c->add_option("--restart-from", a->restart_from,
                "start a new transfer at block N (1-based): the modal state in force at N, up to "
                "the clearance plane, over N's start, down at feed, then N onwards");
  c->add_option("--clearance-z", a->clearance_z_mm,
                "restart: the clearance plane, mm in work coordinates (default: the highest Z "
                "before N)");
  c->add_option("--planner-blocks", a->planner_blocks,
                "ack: the controller's planner, blocks (grbl 1.1: 15), to read Bf:")
      ->capture_default_str();
  c->add_option("--status-hz", a->status_hz,
                "ack: poll the controller's status ('?') this often; 0: never (executed "
                "blocks are then not known)")
      ->capture_default_str();
  c->add_option("--banner-wait", a->banner_wait_s,
                "ack: wait this long for the controller's banner before waking it with an "
                "empty line, s")
      ->capture_default_str();
  c->add_option("--startup-timeout", a->startup_timeout_s,
                "ack: give up when the controller has not spoken after this long, s")
      ->capture_default_str();
  c->add_flag("--unlock", a->unlock,
              "ack: if grbl is in alarm at start-up (locked, e.g. after ALARM:3), clear the lock "
              "with $X before sending; only once the machine has been checked");
  c->add_flag("--controller-skips-repeated-n", a->skips_repeated_n,
              "drip: the controller's manual says it discards a block whose N it already has; "
              "only then are blocks resent after a lost link");
  c->add_flag("-q,--quiet", a->quiet, "no progress lines");
  c->callback([a, c, &run] {
    service::note_given_flags(
        *c, a->link,
        {"--port", "--rx-buffer", "--max-queued", "--xoff-timeout", "--reconnect-max"});
    run = [a] { return run_stream(*a); };
  });
}

}  // namespace ncd::app
