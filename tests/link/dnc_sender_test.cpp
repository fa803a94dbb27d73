// The sender's parts against independent expectations: line arithmetic from the spec, the
// journal on disk, program files, and the drip-feed stop distance measured on a real
// pseudo-terminal with a peer written here (no simulated controller involved).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <thread>
#include <vector>

#include "core/error.hpp"
#include "gcode/dialect/program_modal.hpp"
#include "link/dnc_sender.hpp"
#include "link/live_blocks.hpp"
#include "link/program_file.hpp"
#include "link/pty.hpp"
#include "link/sha256.hpp"
#include "link/transfer_journal.hpp"

namespace ncd::comms {
namespace {

namespace fs = std::filesystem;

TEST(LineSettings, CharacterCostFromTheSpec) {
  LineSettings l;
  parse_frame("7E2", l);
  EXPECT_EQ(bits_per_char(l), 11);
  EXPECT_NEAR(chars_per_s(l), 1745.45, 0.01);  // spec: about 1 745 characters per second
  parse_frame("8N1", l);
  EXPECT_EQ(bits_per_char(l), 10);
  parse_frame("8o2", l);
  EXPECT_EQ(l.parity, Parity::Odd);
  EXPECT_EQ(bits_per_char(l), 12);
  for (const char* bad : {"", "9N1", "8X1", "8N3", "7E22", "E72"}) {
    EXPECT_THROW(parse_frame(bad, l), InputError) << bad;
  }
  EXPECT_THROW(check_baud(12345), InputError);
  EXPECT_NO_THROW(check_baud(19200));
  EXPECT_THROW(parse_flow("hw"), InputError);
  EXPECT_THROW(parse_protocol("zmodem"), InputError);
}

TEST(Sha256, KnownDigests) {
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  Sha256 h;
  h.update("a");
  h.update("bc");
  EXPECT_EQ(h.hex(), sha256_hex("abc"));
}

fs::path temp(const std::string& name) {
  return fs::temp_directory_path() / ("ncd_sender_" + std::to_string(getpid()) + "_" + name);
}

JournalState journal_state(const std::string& sha, const std::string& settings,
                           std::int64_t blocks) {
  JournalState s;
  s.program_sha256 = sha;
  s.settings = settings;
  s.blocks = blocks;
  return s;
}

TEST(TransferJournal, RecordsTheResumePointInPlace) {
  const fs::path p = temp("journal");
  const JournalState s = journal_state("ab", "19200 7E2 xonxoff drip LF", 1000);
  {
    TransferJournal j(p.string(), s);
    const auto size0 = fs::file_size(p);
    for (std::int64_t k = 1; k <= 999; ++k) j.confirm(k);
    j.confirm(10);                       // never backwards
    EXPECT_EQ(fs::file_size(p), size0);  // the record is overwritten, the file does not grow
    const auto r = TransferJournal::read(p.string());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->confirmed, 999);
    EXPECT_FALSE(r->complete);
    EXPECT_EQ(r->settings, s.settings);
    j.complete();
  }
  EXPECT_TRUE(TransferJournal::read(p.string())->complete);
  std::ofstream(p) << "not a journal\n";
  EXPECT_THROW(TransferJournal::read(p.string()), InputError);
  fs::remove(p);
  EXPECT_FALSE(TransferJournal::read(p.string()));
}

// A journal being made again (a resume starts a new one at the same path) is never seen half
// written: a reader polling it, as Stream.KilledSenderResumesFromItsJournal does and as a
// resume after a kill at any instant would, reads the old journal or the new one. Before the
// journal was made beside its path and renamed, CI's end-to-end run read it truncated.
TEST(TransferJournal, AReaderNeverSeesItHalfMade) {
  const fs::path p = temp("journal_race");
  const JournalState s = journal_state("cd", "9600 7E2 xonxoff drip LF", 500);
  { TransferJournal first(p.string(), s); }
  std::atomic<bool> done{false};
  std::thread maker([&] {
    for (int k = 0; k < 300; ++k) {
      JournalState next = s;
      next.confirmed = k;
      TransferJournal j(p.string(), next);
      j.confirm(k + 1);
    }
    done = true;
  });
  long reads = 0;
  std::string half_made;
  while (!done.load() && half_made.empty()) {
    try {
      const auto r = TransferJournal::read(p.string());
      if (!r || r->blocks != 500) half_made = "no journal, or another one";
      ++reads;
    } catch (const InputError& e) {
      half_made = e.what();  // "not usable (truncated)"
    }
  }
  maker.join();
  EXPECT_EQ(half_made, "") << "after " << reads << " reads";
  std::printf("[ measured ] %ld reads beside 300 journals made anew\n", reads);
  EXPECT_GT(reads, 0);
  int leftovers = 0;
  for (const auto& e : fs::directory_iterator(p.parent_path())) {
    leftovers += e.path().filename().string().rfind(p.filename().string() + ".tmp", 0) == 0;
  }
  EXPECT_EQ(leftovers, 0);  // no temporary left beside it
  fs::remove(p);
}

// The bound on the blocks written: always past the block about to be written (read back after
// each call, as a sender killed right after the write would leave it), raised by a margin so
// that the record is rewritten once per kSentMargin blocks; a journal from before the bound
// reads as "every block may have been written".
TEST(TransferJournal, SentBoundIsAlwaysPastTheBlockWritten) {
  const fs::path p = temp("journal_sent");
  JournalState s;
  s.program_sha256 = "ab";
  s.settings = "115200 8N1 none ack LF";
  s.blocks = 100;
  {
    TransferJournal j(p.string(), s);
    std::int64_t raised = 0, last = -1;
    for (std::int64_t k = 0; k < 100; ++k) {
      j.note_writing(k);
      const auto r = TransferJournal::read(p.string());
      ASSERT_TRUE(r);
      EXPECT_GT(r->sent_bound, k);
      EXPECT_LE(r->sent_bound, 100);
      raised += r->sent_bound != last ? 1 : 0;
      last = r->sent_bound;
    }
    EXPECT_EQ(raised, 4);  // 0 → 32, 64, 96, 100
  }
  std::ofstream(p) << R"({"journal":"ncd-transfer-journal-1","program_sha256":"ab",)"
                   << R"("settings":"x","blocks":100})"
                   << "\nconfirmed 000000000042 complete 0\n";
  const auto old = TransferJournal::read(p.string());
  ASSERT_TRUE(old);
  EXPECT_EQ(old->confirmed, 42);
  EXPECT_EQ(old->sent_bound, 100);
  fs::remove(p);
}

TEST(ProgramFile, FramingIsNotABlock) {
  EXPECT_EQ(block_of_line("%"), "");
  EXPECT_EQ(block_of_line(std::string("\0\0%\r", 4)), "");
  EXPECT_EQ(block_of_line("  N1G1X1\r"), "N1G1X1");
  const fs::path p = temp("prog.ngc");
  std::ofstream(p) << std::string("\0\0", 2) << "%\r\nN1G1X1\r\n\r\nN2G1X2\r\n%\r\n";
  const ProgramSummary s = scan_program(p.string(), 7, 256);
  EXPECT_EQ(s.blocks, 2);
  EXPECT_EQ(s.sha256, sha256_hex("N1G1X1\nN2G1X2\n"));
  EXPECT_TRUE(s.numbered);
  EXPECT_THROW(scan_program(p.string(), 7, 5), InputError);  // block longer than allowed
  std::ofstream(p) << "%\n%\n";
  EXPECT_THROW(scan_program(p.string(), 7, 256), InputError);  // no blocks
  fs::remove(p);
}

// grbl 1.1's status report as report.c writes it; anything else is not one.
TEST(GrblStatus, ParsesTheFieldsTheLinkUses) {
  const auto st = parse_grbl_status("<Run|MPos:1.000,-2.500,0.000|Bf:14,120|Ln:40|FS:500,0>");
  ASSERT_TRUE(st);
  EXPECT_EQ(st->state, "Run");
  EXPECT_EQ(*st->mpos, (std::array<double, 3>{1.0, -2.5, 0.0}));
  EXPECT_EQ(st->free_blocks, 14);
  EXPECT_EQ(st->free_bytes, 120);
  EXPECT_EQ(st->line_number, 40);
  const auto w = parse_grbl_status("<Hold:0|WPos:0.000,0.000,5.000|WCO:1.000,2.000,3.000>");
  ASSERT_TRUE(w);
  EXPECT_EQ(w->state, "Hold:0");
  EXPECT_FALSE(w->mpos);
  EXPECT_EQ((*w->wpos)[2], 5.0);
  EXPECT_EQ((*w->wco)[1], 2.0);
  EXPECT_FALSE(w->free_blocks);
  for (const char* bad : {"ok", "<Idle>", "<Idle|MPos:1,x,3>", "<|MPos:0,0,0>", "Idle|MPos:0,0,0",
                          "<Idle|MPos:0,0,0|Bf:15>", ""}) {
    EXPECT_FALSE(parse_grbl_status(bad)) << bad;
  }
}

// grbl's count of a line: spaces, control characters and comments removed (protocol.c).
TEST(GrblLine, CharactersKeptAreCountedAsGrblDoes) {
  EXPECT_EQ(grbl_line_chars("G1 X1 Y2"), 6);
  EXPECT_EQ(grbl_line_chars("G1 (a comment) X1 ; rest"), 4);
  EXPECT_EQ(grbl_line_chars("(only a comment)"), 0);
  EXPECT_EQ(grbl_line_chars(std::string(79, 'X')), 79);
  EXPECT_EQ(grbl_line_chars(")" + std::string(80, 'X')), 81);  // the sender's line flush
}

// The modal reader: end points in mm (inch and incremental included) and the restart lines,
// which a hand-written expectation gives here.
TEST(ProgramModal, EndPointsAndRestartBlocks) {
  ProgramModal m;
  EXPECT_FALSE(m.apply("G20 G90 G55 T3 M6 G43 H3").motion);
  const BlockMotion a = m.apply("S12000 M3 M8 G0 X1 Y2 Z0.5");
  EXPECT_TRUE(a.motion);
  EXPECT_EQ(a.to_mm, (std::array<double, 3>{25.4, 50.8, 12.7}));
  EXPECT_FALSE(m.apply("G91").motion);
  const BlockMotion b = m.apply("G1 X1 F20");  // incremental, in inches
  EXPECT_EQ(b.from_mm, a.to_mm);
  EXPECT_EQ(b.to_mm, (std::array<double, 3>{50.8, 50.8, 12.7}));
  EXPECT_FALSE(m.apply("G4 P1").motion);
  EXPECT_FALSE(m.apply("G28").known);
  const auto lines = restart_blocks(m.state(), 25.4);  // the clearance plane at 1 inch
  const std::vector<std::string> expect = {"(ncd restart: the modes in force at the restart block)",
                                           "G20 G90 G55",
                                           "T3 M6",
                                           "G43 H3",
                                           "G0 Z1",
                                           "S12000 M3",
                                           "M8",
                                           "G0 X2 Y2",
                                           "G1 Z0.5 F20",
                                           "G91 G1 F20"};
  EXPECT_EQ(lines, expect);
  ProgramModal none;
  EXPECT_THROW(restart_blocks(none.state(), 5.0), InputError);  // no feed in force
}

// The restart lines are checked against the controller's dialect as it receives them: for a
// grbl machine the same state written with a tool change and a G43 H is refused (grbl 1.1 has
// neither M6 nor G43 H: error:20), naming the line and the word; without them grbl takes every
// line, and so does an iso control.
TEST(ProgramModal, RestartBlocksAreCheckedAgainstTheDialect) {
  ProgramModal m;
  m.apply("G20 G90 G55 T3 M6 G43 H3");
  m.apply("S12000 M3 G0 X1 Y2 Z0.5");
  m.apply("G1 X2 F20");
  EXPECT_NO_THROW(restart_blocks(m.state(), 25.4, Dialect::iso));
  EXPECT_NO_THROW(restart_blocks(m.state(), 25.4, Dialect::linuxcnc));
  try {
    restart_blocks(m.state(), 25.4, Dialect::grbl);
    ADD_FAILURE() << "a T3 M6 restart line was taken for grbl";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("line 3 'T3 M6'"), std::string::npos) << what;
    EXPECT_NE(what.find("error:20"), std::string::npos) << what;
  }
  ProgramModal g;  // a grbl program: T without M6, no length offset
  g.apply("G21 G90 T2");
  g.apply("S8000 M3 G0 X10 Y5 Z2");
  g.apply("G1 Z-1 F300");
  const auto lines = restart_blocks(g.state(), 5.0, Dialect::grbl);
  GrblState grbl;
  for (const auto& line : lines) EXPECT_FALSE(check_grbl_line(line, grbl)) << line;
}

// Drip feed: after the controller's DC3 the sender stops within max_queued_chars characters,
// give or take the DC3's own way across the pty,
// and the program still arrives whole once DC1 comes.
TEST(DncSender, DripStopsWithinTheQueueLimitAfterXoff) {
  // The test plays the controller on the master side of the project's own pty pair.
  Pty pty(temp("link").string());
  LiveBlocks blocks;
  std::string expect;
  for (int i = 1; i <= 250; ++i) {
    const std::string b = "N" + std::to_string(i) + "G1X" + std::to_string(i) + ".5Y-1.25";
    blocks.push(b);
    expect += b + "\n";
  }
  blocks.close();
  SenderSettings s;
  s.line.device = pty.device();
  s.line.baud = 38400;
  s.line.percent_framing = false;
  s.max_queued_chars = 16;
  DncSender sender(s, blocks);
  std::atomic<bool> stop{false};
  SenderReport report;
  std::thread t([&] { report = sender.run(stop); });

  std::string got;
  std::vector<std::size_t> after_xoff;  // characters the sender wrote after each DC3
  std::vector<double> carried;          // what the line carries from the DC3 to the last of them
  const auto t0 = std::chrono::steady_clock::now();
  int cycle = 0;
  while (got.size() < expect.size() &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(20)) {
    // Read freely for 30 ms, then DC3, then count what still arrives for 50 ms, then DC1.
    auto last = std::chrono::steady_clock::now();  // when the last character came
    const auto read_for = [&](int ms) {
      std::size_t n = 0;
      const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
      while (std::chrono::steady_clock::now() < end) {
        pollfd p{pty.master(), POLLIN, 0};
        if (::poll(&p, 1, 1) > 0) {
          char buf[256];
          const ssize_t r = ::read(pty.master(), buf, sizeof buf);
          if (r > 0) {
            got.append(buf, static_cast<std::size_t>(r));
            n += static_cast<std::size_t>(r);
            last = std::chrono::steady_clock::now();
          }
        }
      }
      return n;
    };
    read_for(30);
    const char xoff = kXoff, xon = kXon;
    int waiting = 0;  // written before the DC3 but not read yet: not the sender's overrun
    ASSERT_EQ(::ioctl(pty.master(), FIONREAD, &waiting), 0);
    ASSERT_EQ(::write(pty.master(), &xoff, 1), 1);
    const auto t_xoff = std::chrono::steady_clock::now();
    last = t_xoff;
    after_xoff.push_back(read_for(50) - static_cast<std::size_t>(waiting));
    carried.push_back(chars_per_s(s.line) * std::chrono::duration<double>(last - t_xoff).count());
    ASSERT_EQ(::write(pty.master(), &xon, 1), 1);
    ++cycle;
  }
  t.join();
  EXPECT_TRUE(report.completed) << report.failure;
  EXPECT_EQ(got, expect);
  EXPECT_GT(cycle, 5);
  // The sender keeps at most 16 characters ahead of its wire model; the DC3 itself takes a
  // moment to cross the pty and reach the sender, while the model drains at line speed. So
  // after each DC3: at most 16 plus what the line carried from the DC3 to the last character
  // that followed it (measured, not assumed: a loaded machine delays the sender; 5 ms of line,
  // 17 characters at 38 400 7E2, when idle).
  for (std::size_t i = 0; i < after_xoff.size(); ++i) {
    EXPECT_LE(static_cast<double>(after_xoff[i]), 16.0 + std::ceil(carried[i]) + 1.0)
        << "DC3 " << i << ": " << after_xoff[i] << " characters after it, " << carried[i]
        << " carried by the line meanwhile";
  }
  // And as a rule 16 (a sender that ignored DC3 would write some 170 in the 50 ms).
  std::sort(after_xoff.begin(), after_xoff.end());
  EXPECT_LE(after_xoff[after_xoff.size() / 2], 16U);
  std::cout << "[ measured ] characters after a DC3: median " << after_xoff[after_xoff.size() / 2]
            << ", most " << after_xoff.back() << " (" << after_xoff.size() << " DC3s)\n";
  EXPECT_GT(report.xoff_count, 5);
  EXPECT_EQ(report.program_sha256, sha256_hex(expect));
}

// The live counters (SenderCounts) against what the test's own controller side sees on the
// pty. The source gives its blocks in batches; the test gives the next batch only once the
// counters show the sender dry after the last one, so every batch but the last (after which
// the source is closed) ends in exactly one underrun. While the sender runs, the counters
// only grow; the bytes it has written are at least what the test has read; a DC3 from the test
// shows as xoff_held and one more xoff_count while the sender still runs; and at the end every
// counter equals the report's and the bytes the test read.
// A source whose blocks are released a batch at a time, atomically (so that the sender never
// sees half a batch), and closed with the last.
class BatchSource : public BlockSource {
 public:
  void release(std::vector<std::string> batch, bool last) {
    std::lock_guard lock(mutex_);
    for (auto& b : batch) queue_.push_back(std::move(b));
    closed_ = last;
  }
  BlockStatus next(std::string& text) override {
    std::lock_guard lock(mutex_);
    if (queue_.empty()) return closed_ ? BlockStatus::End : BlockStatus::NotYet;
    text = std::move(queue_.front());
    queue_.pop_front();
    return BlockStatus::Ready;
  }

 private:
  std::mutex mutex_;
  std::deque<std::string> queue_;
  bool closed_ = false;
};

TEST(DncSender, LiveCountersGrowCountEachUnderrunOnceAndEndAsTheReport) {
  Pty pty(temp("live").string());
  BatchSource blocks;
  SenderSettings s;
  s.line.device = pty.device();
  s.line.baud = 115200;
  s.line.percent_framing = false;
  s.max_queued_chars = 16;
  DncSender sender(s, blocks);
  std::atomic<bool> stop{false};
  SenderReport report;
  std::thread t([&] { report = sender.run(stop); });

  std::string got, expect;
  const auto read_some = [&] {
    pollfd p{pty.master(), POLLIN, 0};
    if (::poll(&p, 1, 1) > 0) {
      char buf[256];
      const ssize_t r = ::read(pty.master(), buf, sizeof buf);
      if (r > 0) got.append(buf, static_cast<std::size_t>(r));
    }
  };
  SenderCounts last;
  const auto check = [&](const SenderCounts& c) {
    EXPECT_GE(c.bytes_written, last.bytes_written);
    EXPECT_GE(c.blocks_taken, last.blocks_taken);
    EXPECT_GE(c.blocks_written, last.blocks_written);
    EXPECT_GE(c.xoff_count, last.xoff_count);
    EXPECT_GE(c.underruns, last.underruns);
    EXPECT_LE(c.blocks_written, c.blocks_taken);
    EXPECT_EQ(c.blocks_acked, -1);  // drip: no answer
    EXPECT_EQ(c.buffer_limit_bytes, 16);
    EXPECT_GE(c.buffer_bytes, 0);
    last = c;
  };
  // Waits (reading the line) until the counters satisfy `pred`; false after 20 s.
  const auto wait_for = [&](auto pred) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (std::chrono::steady_clock::now() < until) {
      read_some();
      const SenderCounts c = sender.counters().load();
      check(c);
      if (pred(c)) return true;
    }
    return false;
  };
  constexpr int kBatches = 6, kPerBatch = 5;
  int n = 0;
  std::int64_t want_underruns = 0;
  for (int b = 0; b < kBatches; ++b) {
    std::vector<std::string> batch;
    for (int i = 0; i < kPerBatch; ++i) {
      ++n;
      batch.push_back("N" + std::to_string(n) + "G1X" + std::to_string(n) + ".5");
      expect += batch.back() + "\n";
    }
    blocks.release(std::move(batch), b + 1 == kBatches);
    if (b + 1 == kBatches) break;
    // The sender takes the batch, writes it, and runs dry: one underrun per batch.
    ++want_underruns;
    ASSERT_TRUE(wait_for([&](const SenderCounts& c) { return c.underruns == want_underruns; }))
        << "batch " << b << ": " << last.underruns << " underruns, " << last.blocks_written
        << " blocks written";
    EXPECT_EQ(last.blocks_written, n);
    EXPECT_EQ(last.blocks_taken, n);
    if (b == 2) {  // a DC3 while it runs: held, counted; then DC1
      const char xoff = kXoff, xon = kXon;
      ASSERT_EQ(::write(pty.master(), &xoff, 1), 1);
      ASSERT_TRUE(wait_for([](const SenderCounts& c) { return c.xoff_held; }));
      EXPECT_EQ(last.xoff_count, 1);
      ASSERT_EQ(::write(pty.master(), &xon, 1), 1);
      // Released with nothing to send: a new dry spell, counted as such.
      ++want_underruns;
      ASSERT_TRUE(wait_for(
          [&](const SenderCounts& c) { return !c.xoff_held && c.underruns == want_underruns; }));
      EXPECT_EQ(last.blocks_written, n);
    }
  }
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (got.size() < expect.size() && std::chrono::steady_clock::now() < until) read_some();
  t.join();
  const SenderCounts c = sender.counters().load();
  check(c);
  EXPECT_TRUE(report.completed) << report.failure;
  EXPECT_EQ(got, expect);
  // kBatches − 1 dry spells after the batches, one more after the DC1.
  EXPECT_EQ(c.underruns, kBatches);
  EXPECT_EQ(c.bytes_written, report.bytes_written);
  EXPECT_EQ(c.bytes_written, static_cast<std::int64_t>(got.size()));
  EXPECT_EQ(c.blocks_taken, report.blocks);
  EXPECT_EQ(c.blocks_written, report.blocks_sent);
  EXPECT_EQ(c.blocks_written, kBatches * kPerBatch);
  EXPECT_EQ(c.xoff_count, report.xoff_count);
  EXPECT_EQ(c.xoff_count, 1);
  EXPECT_FALSE(c.xoff_held);
  EXPECT_EQ(c.reconnects, report.reconnects);
  EXPECT_EQ(c.link_losses, report.link_losses);
}

}  // namespace
}  // namespace ncd::comms
