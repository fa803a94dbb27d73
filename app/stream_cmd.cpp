// `ncd stream`: send an NC program to a controller over RS-232 DNC and exit 0 once the
// controller has all of it (confirmed, for the acknowledged protocol). A transfer journal next
// to the program lets a stopped or killed transfer resume from the first unconfirmed block.
// Exit status: 0 sent, 2 invalid input, 3 the transfer did not complete (controller alarm,
// link given up, or stopped by a signal; the journal says where to resume).
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/commands.hpp"
#include "app/link_options.hpp"
#include "app/output.hpp"
#include "comms/dnc_sender.hpp"
#include "comms/program_file.hpp"
#include "comms/transfer_journal.hpp"
#include "core/error.hpp"

namespace ncd::app {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int /*signal*/) {
  g_stop.store(true);
}

struct StreamArgs {
  std::string program, port, journal, report;
  LinkFlags link;
  int max_queued_chars = 16;
  int rx_buffer_bytes = 128;
  double xoff_timeout_s = 5.0;
  double reconnect_max_s = 30.0;
  bool resume = false, restart = false, no_journal = false, quiet = false;
};

std::string fmt(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

nlohmann::json report_json(const comms::SenderReport& r, const comms::LineSettings& line,
                           const std::string& program, const std::string& journal) {
  return {{"program", program},
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
          {"program_bytes", r.program_bytes},
          {"program_sha256", r.program_sha256},
          {"duration_s", r.duration_s},
          {"link_use", r.link_use},
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

int run_stream(const StreamArgs& a) {
  const comms::LineSettings line = line_settings(a.link, a.port);
  require_positive("--xoff-timeout (s)", a.xoff_timeout_s);
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
  const int max_block = line.protocol == comms::Protocol::Ack ? a.rx_buffer_bytes - 2 : 4096;
  const comms::ProgramSummary program = comms::scan_program(a.program, line.data_bits, max_block);
  require_serial_port(a.port, "--port");  // a file or a missing port: exit 2 now, no retries

  // The journal: resume where a previous transfer of the same program stopped.
  const std::string journal_path =
      a.no_journal ? "" : (a.journal.empty() ? a.program + ".journal" : a.journal);
  std::int64_t first_block = 0;
  if (!journal_path.empty() && !a.restart) {
    const auto previous = comms::TransferJournal::read(journal_path);
    if (previous && !previous->complete) {
      if (previous->program_sha256 != program.sha256) {
        throw InputError("the journal " + journal_path +
                         " belongs to a different program (its checksum differs): pass "
                         "--restart to send this program from the start, or --journal FILE");
      }
      if (!a.resume) {
        throw InputError("a transfer of " + a.program + " stopped at block " +
                         std::to_string(previous->confirmed + 1) + " of " +
                         std::to_string(previous->blocks) + " (journal " + journal_path +
                         "): pass --resume to continue there, or --restart to send it all again");
      }
      first_block = previous->confirmed;
      if (previous->settings != comms::describe(line)) {
        std::cerr << "ncd stream: warning: the journal was written at " << previous->settings
                  << ", now " << comms::describe(line) << "\n";
      }
    } else if (a.resume) {
      throw InputError("--resume: there is no unfinished transfer in " + journal_path +
                       "; run without --resume to send the program");
    }
  }
  std::unique_ptr<comms::TransferJournal> journal;
  if (!journal_path.empty()) {
    comms::JournalState start;
    start.program_sha256 = program.sha256;
    start.settings = comms::describe(line);
    start.blocks = program.blocks;
    start.confirmed = first_block;
    journal = std::make_unique<comms::TransferJournal>(journal_path, start);
  }

  comms::SenderSettings settings;
  settings.line = line;
  settings.max_queued_chars = a.max_queued_chars;
  settings.rx_buffer_bytes = a.rx_buffer_bytes;
  settings.xoff_timeout_s = a.xoff_timeout_s;
  settings.reconnect_max_s = a.reconnect_max_s;
  comms::ProgramFile source(a.program);
  const bool quiet = a.quiet;
  comms::DncSender sender(settings, source, [quiet](const comms::SenderEvent& e) {
    if (quiet && e.kind == comms::SenderEvent::Kind::Progress) return;
    std::cerr << "ncd stream: [" << fmt(e.t_s, 3) << " s] " << e.text << std::endl;
  });
  sender.set_journal(journal.get());
  sender.resume_from(first_block);
  if (!quiet) {
    std::cerr << "ncd stream: " << a.program << ": " << program.blocks << " blocks, "
              << program.bytes << " bytes, sha256 " << program.sha256 << "\n"
              << "ncd stream: " << comms::describe(line) << " carries "
              << fmt(comms::chars_per_s(line), 0) << " characters/s; at least "
              << fmt(static_cast<double>(program.bytes) / comms::chars_per_s(line), 1)
              << " s on the wire"
              << (first_block > 0 ? "; resuming at block " + std::to_string(first_block + 1) : "")
              << std::endl;
  }

  g_stop.store(false);
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  const comms::SenderReport r = sender.run(g_stop);

  if (!a.report.empty()) {
    write_output(a.report, report_json(r, line, a.program, journal_path).dump(2) + "\n");
  }
  std::cout << (r.completed ? "sent " : "NOT COMPLETE: ") << r.blocks - r.first_block << " blocks ("
            << r.bytes_written << " bytes) in " << fmt(r.duration_s, 2) << " s, "
            << fmt(100.0 * r.link_use, 1) << " % of the line; XOFF " << r.xoff_count
            << " times (longest " << fmt(r.xoff_longest_s, 2) << " s), " << r.reconnects
            << " reconnects, " << r.blocks_resent << " blocks resent, " << r.noise_bytes
            << " noise bytes ignored\n"
            << "program sha256 " << r.program_sha256 << "\n";
  if (r.completed) {
    if (!journal_path.empty()) std::filesystem::remove(journal_path);
    return 0;
  }
  std::cout << (r.stopped ? "stopped" : "failed: " + r.failure) << "; the controller has "
            << r.blocks_confirmed << " blocks confirmed"
            << (journal_path.empty() ? "" : "; resume with --resume (journal " + journal_path + ")")
            << "\n";
  return 3;
}

}  // namespace

void register_stream(CLI::App& app, Runner& run) {
  auto a = std::make_shared<StreamArgs>();
  CLI::App* c = app.add_subcommand(
      "stream",
      "Send an NC program to a controller over RS-232 DNC (drip feed with XON/XOFF or RTS/CTS, "
      "or grbl-type acknowledged streaming). Exits 0 once the controller has all of it, 3 if "
      "the transfer stopped (the journal lets --resume continue at the first unconfirmed "
      "block).");
  c->add_option("program", a->program, "the NC program (one block per line)")->required();
  c->add_option("--port", a->port, "serial device, e.g. /dev/ttyS0 or a sim-controller link")
      ->required();
  add_link_flags(*c, a->link);
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
  c->add_option("--reconnect-max", a->reconnect_max_s,
                "keep reopening a lost port for this long, in s")
      ->capture_default_str();
  c->add_option("--journal", a->journal, "transfer journal (default PROGRAM.journal)");
  c->add_flag("--no-journal", a->no_journal, "keep no journal");
  c->add_flag("--resume", a->resume, "continue an unfinished transfer from its journal");
  c->add_flag("--restart", a->restart, "ignore an unfinished transfer and send it all");
  c->add_option("--report", a->report, "write the transfer report as JSON to this file");
  c->add_flag("-q,--quiet", a->quiet, "no progress lines");
  c->callback([a, &run] { run = [a] { return run_stream(*a); }; });
}

}  // namespace ncd::app
