// The simulated controller over real pseudo-terminals. The controller runs in-process on a
// thread; the sender is written here with plain POSIX open/read/write on the linked path (no
// sender library), and pairs DC1/DC3 with the controller's own count of bytes taken off the wire,
// as a UART with a 16-character FIFO would. Checksums are computed here from the program text.
#include "sim/sim_controller.hpp"
#include "tests/common/temp_dir.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <iterator>
#include <optional>
#include <random>
#include <thread>
#include <vector>

#include "core/error.hpp"
#include "link/dnc_sender.hpp"
#include "link/pty.hpp"
#include "link/sha256.hpp"

namespace ncd::comms {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// A fresh folder per test (tests/common/temp_dir.hpp).
struct TempDir : ncd::test::TempDir {
  TempDir() : ncd::test::TempDir("ncd_sim_") {}
};

// A program of `count` numbered 1 mm G1 moves at `feed`, framed by % and ended by M30. blocks()
// is what the controller must hash; text(eob) what goes on the wire.
struct Program {
  std::vector<std::string> blocks;
  Program(int count, double feed, bool percent = true) : percent_(percent) {
    blocks.push_back("(sim test program)");
    blocks.push_back("G21 G90 G94");
    char buf[96];
    for (int i = 1; i <= count; ++i) {
      std::snprintf(buf, sizeof buf, "N%d G1 X%d Y%.3f F%.0f", i * 10, i, 0.5 * (i % 2), feed);
      blocks.push_back(buf);
    }
    blocks.push_back("N" + std::to_string(count * 10 + 10) + " M30");
  }
  std::string text(const std::string& eob) const {
    std::string s = percent_ ? "%" + eob : "";
    for (const auto& b : blocks) s += b + eob;
    if (percent_) s += "%" + eob;
    return s;
  }
  std::string sha() const {
    std::string s;
    for (const auto& b : blocks) s += b + "\n";
    return sha256_hex(s);
  }
  int moves() const { return static_cast<int>(blocks.size()) - 3; }

 private:
  bool percent_;
};

SimControllerConfig config(const fs::path& link, Protocol protocol = Protocol::Drip,
                           int baud = 115200, const std::string& frame = "8N1") {
  SimControllerConfig c;
  c.line.device = link.string();
  c.line.baud = baud;
  parse_frame(frame, c.line);
  c.line.protocol = protocol;
  c.buffer_bytes = protocol == Protocol::Ack ? 128 : 256;  // grbl's, or a Fanuc-like 256
  c.seed = 1;
  return c;
}

// The controller on its own thread.
class Running {
 public:
  explicit Running(SimControllerConfig cfg)
      : sim(std::move(cfg)), thread_([this] {
          sim.run();
          done_ = true;
        }) {}
  ~Running() { stop(); }
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;

  const SimLog& stop() {
    if (thread_.joinable()) {
      sim.request_stop();
      thread_.join();
    }
    return sim.log();
  }
  // Waits for a condition on the live progress; false after timeout_s.
  template <class Pred>
  bool wait(Pred pred, double timeout_s = 10.0) {
    const auto t0 = Clock::now();
    while (since(t0) < timeout_s) {
      if (pred(sim.progress())) return true;
      std::this_thread::sleep_for(200us);
    }
    return false;
  }
  // With a ManualClock: moves the controller's time on by dt_s and waits (on the wall clock,
  // generously) until its loop has run at the new time, so a loaded machine only slows the test.
  bool step(ManualClock& clock, double dt_s) {
    clock.advance(dt_s);
    const double target = clock.now_s() - t_start_;
    return wait([&](const SimProgress& p) { return p.t_s >= target - 1e-12; }, 30.0);
  }
  void start_clock(const ManualClock& clock) { t_start_ = clock.now_s(); }

  bool wait_end(double timeout_s = 10.0) {
    return wait([](const SimProgress& p) { return p.program_end_executed; }, timeout_s);
  }
  // With a ManualClock: moves the controller's time on in steps of dt_s until the program end
  // has been executed (false after max_s of simulated time).
  bool run_to_end(ManualClock& clock, double dt_s, double max_s) {
    for (double t = 0.0; t < max_s; t += dt_s) {
      if (sim.progress().program_end_executed) return true;
      if (!step(clock, dt_s)) return false;
    }
    return sim.progress().program_end_executed;
  }

  // run() has returned.
  bool done() const { return done_; }

  SimController sim;

 private:
  std::atomic<bool> done_{false};
  double t_start_ = 0.0;
  std::thread thread_;
};

// The sender's end: the linked path opened raw and non-blocking.
class Peer {
 public:
  Peer(const std::string& path, SimController& sim) : sim_(sim) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    EXPECT_GE(fd_, 0) << "cannot open " << path;
    termios t{};
    if (fd_ >= 0 && ::tcgetattr(fd_, &t) == 0) {
      ::cfmakeraw(&t);
      ::tcsetattr(fd_, TCSANOW, &t);
    }
    base_ = sim.progress().bytes_received;
  }
  ~Peer() { close(); }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  bool ok() const { return fd_ >= 0; }

  // Reads what the controller sent; false once the controller's side has hung up.
  bool pump() {
    char buf[512];
    for (;;) {
      const ssize_t n = ::read(fd_, buf, sizeof buf);
      if (n > 0) {
        for (ssize_t i = 0; i < n; ++i) on_byte(buf[i]);
        continue;
      }
      if (n == 0 || (errno != EAGAIN && errno != EINTR)) return false;
      return true;
    }
  }
  // Pumps for a while.
  void listen(double seconds) {
    const auto t0 = Clock::now();
    while (since(t0) < seconds && pump()) std::this_thread::sleep_for(1ms);
  }
  // Characters written and not yet taken off the wire by the controller.
  long ahead() const {
    return static_cast<long>(written_) - static_cast<long>(sim_.progress().bytes_received - base_);
  }
  void write_all(const std::string& bytes) {
    std::size_t off = 0;
    while (off < bytes.size()) {
      const ssize_t n = ::write(fd_, bytes.data() + off, bytes.size() - off);
      if (n > 0) {
        off += static_cast<std::size_t>(n);
      } else {
        std::this_thread::sleep_for(1ms);
      }
    }
    written_ += bytes.size();
  }
  // Drip: sends bytes obeying DC1/DC3 (when `obey`), at most `fifo` characters ahead of the
  // wire. False when the controller hung up or alarmed (NAK) or timeout_s passed.
  bool send_drip(const std::string& bytes, bool obey = true, int fifo = 16,
                 double timeout_s = 60.0) {
    const auto t0 = Clock::now();
    std::size_t off = 0;
    while (off < bytes.size()) {
      if (!pump() || nak_ || since(t0) > timeout_s) return false;
      if ((!obey || xon_) && ahead() < fifo) {
        const std::size_t room = obey ? static_cast<std::size_t>(fifo - ahead()) : bytes.size();
        const std::size_t take = std::min(room, bytes.size() - off);
        const ssize_t n = ::write(fd_, bytes.data() + off, take);
        if (n > 0) {
          off += static_cast<std::size_t>(n);
          written_ += static_cast<std::size_t>(n);
          max_ahead_ = std::max(max_ahead_, ahead());
          continue;
        }
        if (n < 0 && errno != EAGAIN) return false;
      }
      wait_a_little();
    }
    return true;
  }
  // Ack: sends lines (each with its end of block) counting characters within `buffer`; collects
  // the replies (grbl ends a line at CR and at LF: a CR LF line is answered twice). False on an
  // ALARM line, a hang-up or timeout_s.
  bool send_ack(const std::vector<std::string>& lines, int buffer, double timeout_s = 20.0) {
    const auto t0 = Clock::now();
    std::size_t next = 0;
    while (next < lines.size() || !unanswered_.empty()) {
      if (!pump() || since(t0) > timeout_s) return false;
      for (const auto& r : replies) {
        if (r.rfind("ALARM", 0) == 0) return false;
      }
      while (next < lines.size() && used_ + static_cast<int>(lines[next].size()) <= buffer) {
        write_all(lines[next]);
        used_ += static_cast<int>(lines[next].size());
        unanswered_.push_back(static_cast<int>(lines[next].size()));
        const auto ends = std::count_if(lines[next].begin(), lines[next].end(), [](char c) {
          return (c & 0x7F) == '\r' || (c & 0x7F) == '\n';  // a 7-bit line masks bit 8
        });
        for (long extra = 1; extra < ends; ++extra) unanswered_.push_back(0);
        ++next;
      }
      wait_a_little();
    }
    return true;
  }

  // In simulated time: called where the sender would wait, to move the controller's clock on
  // (so the sender reacts within one step of simulated time, whatever the load).
  std::function<bool()> tick;

  std::string received;                        // every byte from the controller
  std::vector<std::string> replies;            // ack: complete lines from the controller
  std::vector<int> fill_at_xoff, fill_at_xon;  // the controller's fill when DC3/DC1 arrived
  bool nak() const { return nak_; }
  long max_ahead() const { return max_ahead_; }

 private:
  void wait_a_little() {
    if (tick) {
      tick();
      return;
    }
    pollfd p{fd_, POLLIN, 0};
    ::poll(&p, 1, 1);
  }

  void on_byte(char c) {
    received += c;
    if (c == kXoff) {
      xon_ = false;
      fill_at_xoff.push_back(sim_.progress().buffer_fill);
    } else if (c == kXon) {
      xon_ = true;
      fill_at_xon.push_back(sim_.progress().buffer_fill);
    } else if (c == kNak) {
      nak_ = true;
    }
    if (c == '\n') {
      std::string line = line_;
      line_.clear();
      if (!line.empty() && line.back() == '\r') line.pop_back();
      replies.push_back(line);
      if ((line == "ok" || line.rfind("error:", 0) == 0) && !unanswered_.empty()) {
        used_ -= unanswered_.front();
        unanswered_.pop_front();
      }
    } else {
      line_ += c;
    }
  }

  SimController& sim_;
  int fd_ = -1;
  std::uint64_t base_ = 0;
  std::size_t written_ = 0;
  bool xon_ = true, nak_ = false;
  long max_ahead_ = 0;
  std::string line_;
  std::deque<int> unanswered_;
  int used_ = 0;
};

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start < text.size()) {
    const auto nl = text.find('\n', start);
    out.push_back(text.substr(start, nl - start + 1));
    start = nl + 1;
  }
  return out;
}

// ---- parsing ----

TEST(SimBlockParse, WordsModalStateAndTimes) {
  SimModal m;
  SimParse p = parse_sim_block("n10 g1 x30 (thirty) f600 ; the rest is a comment", m, 5000);
  ASSERT_EQ(p.error, 0) << p.message;
  EXPECT_EQ(p.block.n, 10);
  EXPECT_TRUE(p.block.move);
  EXPECT_EQ(p.block.g, 1);
  EXPECT_DOUBLE_EQ(p.block.duration_s, 3.0);  // 30 mm at 10 mm/s
  EXPECT_DOUBLE_EQ(m.position[0], 30.0);
  p = parse_sim_block("Y40", m, 5000);  // modal G1 and F600
  ASSERT_EQ(p.error, 0);
  EXPECT_DOUBLE_EQ(p.block.duration_s, 4.0);
  EXPECT_EQ(p.block.to, (std::array<double, 3>{30.0, 40.0, 0.0}));
  p = parse_sim_block("G0 X0 Y0", m, 5000);  // 50 mm at the rapid rate
  EXPECT_DOUBLE_EQ(p.block.duration_s, 50.0 / (5000.0 / 60.0));
  EXPECT_DOUBLE_EQ(p.block.feed_mm_per_min, 5000.0);
  p = parse_sim_block("G4 P0.25", m, 5000);
  EXPECT_FALSE(p.block.move);
  EXPECT_DOUBLE_EQ(p.block.duration_s, 0.25);
  p = parse_sim_block("M30", m, 5000);
  EXPECT_TRUE(p.block.program_end);
  p = parse_sim_block("G64 P0.01 G17 G40 G49 S3000 M3 T1", m, 5000);
  EXPECT_EQ(p.error, 0) << p.message;
  EXPECT_EQ(parse_sim_block("(only a comment)", m, 5000).error, 0);
}

// The rotary index axis (docs/cmd-sim-controller.md): A alone on a G0 turns it at the rapid rate
// read as deg/min, X, Y, Z staying; the modal angle follows; the other axis is then refused.
TEST(SimBlockParse, RotaryIndexAloneOnItsBlock) {
  SimModal m;
  m.position = {1.0, 2.0, 3.0};
  const SimParse p = parse_sim_block("G0 A90", m, 3600);
  ASSERT_EQ(p.error, 0) << p.message;
  EXPECT_TRUE(p.block.move);
  EXPECT_EQ(p.block.to, (std::array<double, 3>{1.0, 2.0, 3.0}));
  EXPECT_EQ(p.block.rotary_axis, 'A');
  EXPECT_EQ(p.block.rotary_to_deg, 90.0);
  EXPECT_DOUBLE_EQ(p.block.duration_s, 90.0 / 60.0);  // 90 degrees at 3600 deg/min
  EXPECT_EQ(m.rotary_deg, 90.0);
  const SimParse back = parse_sim_block("G1 A45 F900", m, 3600);
  ASSERT_EQ(back.error, 0) << back.message;
  EXPECT_DOUBLE_EQ(back.block.duration_s, 45.0 / 15.0);  // 45 degrees at 900 deg/min
  EXPECT_EQ(parse_sim_block("G0 B10", m, 3600).error, kErrUnsupported);
}

TEST(SimBlockParse, GrblErrorCodes) {
  const std::vector<std::pair<std::string, int>> cases = {{"G1 X1", kErrUndefinedFeed},
                                                          {"G91 X1", kErrUnsupported},
                                                          {"G20", kErrUnsupported},
                                                          {"G2 X1 Y1 I1", kErrUnsupported},
                                                          {"G1 Xabc F10", kErrBadNumber},
                                                          {"G1 X F10", kErrBadNumber},
                                                          {"G1 X1 X2 F10", kErrRepeatedWord},
                                                          {"G0 G1 X1", kErrModalGroup},
                                                          {"N1.5 G0 X1", kErrNotInteger},
                                                          {"M99", kErrUnsupported},
                                                          {"G1 X1 F-5", kErrNegative},
                                                          {"#1=2", kErrExpectedLetter},
                                                          {"G4", kErrMissingValue},
                                                          {"N123456789 G0 X1", kErrBadLineNumber},
                                                          {"G0 C1", kErrUnsupported},
                                                          {"G0 X1 A1", kErrUnsupported},
                                                          {"G0 A1 B1", kErrUnsupported},
                                                          {"G5.2 X1", kErrUnsupported},
                                                          {"P5", kErrUnsupported}};
  for (const auto& [text, code] : cases) {
    SimModal m;
    m.position = {1.0, 2.0, 3.0};
    const SimParse p = parse_sim_block(text, m, 5000);
    EXPECT_EQ(p.error, code) << text << ": " << p.message;
    EXPECT_FALSE(p.message.empty()) << text;
    EXPECT_EQ(m.position, (std::array<double, 3>{1.0, 2.0, 3.0})) << "modal changed by " << text;
    EXPECT_EQ(m.feed_mm_per_min, 0.0) << text;
  }
}

TEST(SimControllerConfig, DefaultsAndRanges) {
  SimControllerConfig c;
  c.line.device = "/tmp/x";
  SimControllerConfig d = checked(c);
  EXPECT_EQ(*d.xoff_at, 192);  // 256 − 64: room for a sender that stops within 16 characters
  EXPECT_EQ(*d.xon_at, 96);
  EXPECT_EQ(max_block_chars(d), 190);
  c.buffer_bytes = 128;  // grbl
  d = checked(c);
  EXPECT_EQ(*d.xoff_at, 96);
  EXPECT_EQ(*d.xon_at, 48);
  c.buffer_bytes = 1024;
  EXPECT_EQ(*checked(c).xoff_at, 960);
  c.buffer_bytes = 32;
  EXPECT_THROW(checked(c), InputError);
  c.buffer_bytes = 256;
  c.xoff_at = 300;
  EXPECT_THROW(checked(c), InputError);
  c.xoff_at = 100;
  c.xon_at = 100;
  EXPECT_THROW(checked(c), InputError);
  c.xon_at.reset();
  c.xoff_at.reset();
  c.line.flow = Flow::None;
  c.faults.xoff_storm = true;
  EXPECT_THROW(checked(c), InputError);  // a storm needs DC1/DC3
  c.faults.xoff_storm = false;
  c.faults.noise_bytes_per_s = 1e6;
  EXPECT_THROW(checked(c), InputError);
  c.faults.noise_bytes_per_s = 0.0;
  c.line.device.clear();
  EXPECT_THROW(checked(c), InputError);
}

// ---- the pty ----

TEST(Pty, LinksRawSlaveAndCleansUp) {
  TempDir dir;
  const std::string link = (dir / "cnc").string();
  {
    Pty pty(link);
    EXPECT_EQ(fs::read_symlink(link).string(), pty.device());
    const int fd = ::open(link.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::write(fd, "G1\r\n", 4), 4);
    std::this_thread::sleep_for(20ms);
    char buf[16];
    EXPECT_EQ(::read(pty.master(), buf, sizeof buf), 4);  // CR LF untranslated
    EXPECT_EQ(std::string(buf, 4), "G1\r\n");
    EXPECT_LT(::read(fd, buf, sizeof buf), 0);  // nothing echoed
    ::close(fd);
    std::this_thread::sleep_for(5ms);
    const auto ev = pty.take_slave_events();
    ASSERT_EQ(ev.size(), 2U);
    EXPECT_EQ(ev[0], Pty::SlaveEvent::Opened);
    EXPECT_EQ(ev[1], Pty::SlaveEvent::Closed);
    pty.close();
    EXPECT_FALSE(fs::is_symlink(link));
    pty.open();  // recreate
    EXPECT_TRUE(fs::is_symlink(link));
  }
  EXPECT_FALSE(fs::is_symlink(link));
}

TEST(Pty, ReplacesALinkRefusesAnythingElse) {
  TempDir dir;
  const std::string link = (dir / "cnc").string();
  fs::create_symlink("/nonexistent/old", link);
  {
    Pty pty(link);
    EXPECT_EQ(fs::read_symlink(link).string(), pty.device());
  }
  std::ofstream(dir / "file") << "keep me";
  EXPECT_THROW(Pty((dir / "file").string()), InputError);
  EXPECT_EQ(fs::file_size(dir / "file"), 7U);
  EXPECT_THROW(Pty((dir / "missing" / "cnc").string()), InputError);
}

// ---- byte-exact transfer ----

struct ExactCase {
  Protocol protocol;
  const char* eob;
  const char* frame;
};

// How the case appears in test names and failure messages.
void PrintTo(const ExactCase& c, std::ostream* os) {
  *os << (c.protocol == Protocol::Drip ? "drip " : "ack ")
      << (std::string(c.eob) == "\n" ? "LF " : "CRLF ") << c.frame;
}

class ByteExact : public ::testing::TestWithParam<ExactCase> {};

TEST_P(ByteExact, ProgramArrivesWithItsChecksum) {
  const ExactCase k = GetParam();
  TempDir dir;
  const Program prog(30, 3000.0, k.protocol == Protocol::Drip);  // 20 ms a block
  SimControllerConfig cfg = config(dir / "cnc", k.protocol, 19200, k.frame);
  cfg.line.eob = std::string(k.eob) == "\r\n" ? EndOfBlock::CrLf : EndOfBlock::Lf;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  std::vector<std::string> lines = lines_of(prog.text(k.eob));
  std::string wire;
  for (auto& line : lines) {
    if (std::string(k.frame) == "7E2") {
      for (char& c : line) c = static_cast<char>(c | 0x80);  // a 7-bit UART never sees bit 8
    }
    wire += line;
  }
  if (k.protocol == Protocol::Drip) {
    ASSERT_TRUE(peer.send_drip(wire));
    EXPECT_LE(peer.max_ahead(), 16);
  } else {
    ASSERT_TRUE(peer.send_ack(lines, cfg.buffer_bytes));
  }
  ASSERT_TRUE(run.wait_end());
  if (k.protocol == Protocol::Ack) {
    const std::size_t per_line = std::string(k.eob) == "\r\n" ? 2 : 1;  // grbl: CR ends a line
    const std::size_t want = prog.blocks.size() * per_line;
    const auto t0 = Clock::now();
    while (peer.replies.size() < want && since(t0) < 10.0 && peer.pump()) {
      std::this_thread::sleep_for(1ms);
    }
    EXPECT_EQ(peer.replies, std::vector<std::string>(want, "ok"));
  }
  // M30 ends the program before the closing `%` has come off the wire: wait for it.
  EXPECT_TRUE(run.wait([&](const SimProgress& p) { return p.bytes_received >= wire.size(); }));
  peer.pump();
  const SimLog& log = run.stop();
  EXPECT_EQ(log.program_sha256, prog.sha());
  EXPECT_EQ(log.blocks_received, static_cast<long>(prog.blocks.size()));
  EXPECT_EQ(log.bytes_received, wire.size());
  EXPECT_TRUE(log.program_end_received);
  EXPECT_TRUE(log.program_end_executed);
  EXPECT_TRUE(log.alarms.empty());
  EXPECT_LE(log.max_buffer_fill, cfg.buffer_bytes);
  ASSERT_EQ(static_cast<int>(log.moves.size()), prog.moves());
  EXPECT_EQ(log.moves.back().p, (std::array<double, 3>{30.0, 0.0, 0.0}));
  EXPECT_EQ(log.moves.back().n, 300);
  EXPECT_DOUBLE_EQ(log.moves.back().feed_mm_per_min, 3000.0);
  EXPECT_LE(log.link_use, 1.0);
  if (k.protocol == Protocol::Drip) {
    EXPECT_GE(log.xoff_sent, 1);  // 11 ms on the wire, 20 ms to execute: the buffer fills
    EXPECT_EQ(peer.received.front(), kXon);  // ready
  } else {
    EXPECT_EQ(log.xoff_sent, 0);
    EXPECT_LE(log.max_planner_blocks, 15);  // grbl 1.1's planner, never more
  }
}

INSTANTIATE_TEST_SUITE_P(SimController, ByteExact,
                         ::testing::Values(ExactCase{Protocol::Drip, "\n", "7E2"},
                                           ExactCase{Protocol::Drip, "\n", "8N1"},
                                           ExactCase{Protocol::Drip, "\r\n", "7E2"},
                                           ExactCase{Protocol::Drip, "\r\n", "8N1"},
                                           ExactCase{Protocol::Ack, "\n", "7E2"},
                                           ExactCase{Protocol::Ack, "\n", "8N1"},
                                           ExactCase{Protocol::Ack, "\r\n", "7E2"},
                                           ExactCase{Protocol::Ack, "\r\n", "8N1"}),
                         [](const ::testing::TestParamInfo<ExactCase>& param_info) {
                           const ExactCase& c = param_info.param;
                           return std::string(c.protocol == Protocol::Drip ? "Drip" : "Ack") +
                                  (std::string(c.eob) == "\n" ? "Lf" : "CrLf") + c.frame;
                         });

// ---- pacing ----

// Writes `chars` at once into a controller with a buffer large enough to take them and measures
// how long the controller takes to read them off the pty. Returns the log.
SimLog pace(const fs::path& link, int baud, const std::string& frame, int chars,
            double& elapsed_s) {
  SimControllerConfig cfg = config(link, Protocol::Drip, baud, frame);
  cfg.line.flow = Flow::None;
  cfg.buffer_bytes = 8192;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  std::string text;
  while (static_cast<int>(text.size()) + 20 <= chars) text += "(pacing test 0123)\n";
  text += std::string(static_cast<std::size_t>(chars) - text.size() - 1, ' ') + "\n";
  const auto t0 = Clock::now();
  peer.write_all(text);
  EXPECT_TRUE(run.wait(
      [&](const SimProgress& p) { return p.bytes_received >= static_cast<std::uint64_t>(chars); }));
  elapsed_s = since(t0);
  return run.stop();
}

TEST(SimController, PacesReceptionAtTheLineRate) {
  TempDir dir;
  double elapsed = 0.0;
  SimLog log = pace(dir / "cnc", 19200, "7E2", 1000, elapsed);
  const double cps = 19200.0 / 11.0;  // 1745.45 characters a second (docs/dnc-link.md)
  std::cout << "[ measured ] 1000 chars at 19200 7E2: " << elapsed << " s (line: " << 1000 / cps
            << " s), controller's bytes_per_s " << log.bytes_per_s << ", link_use " << log.link_use
            << "\n";
  EXPECT_EQ(log.bytes_received, 1000U);
  EXPECT_GE(elapsed, 1000.0 / cps);  // never faster than the line; slower under load is fine
  EXPECT_LE(log.bytes_per_s, cps * (1.0 + 1e-9));
  EXPECT_GE(log.reception_s, 1000.0 / cps - 1e-9);

  log = pace(dir / "cnc", 115200, "8N1", 5000, elapsed);
  std::cout << "[ measured ] 5000 chars at 115200 8N1: " << elapsed
            << " s (line: " << 5000 / 11520.0 << " s), link_use " << log.link_use << "\n";
  EXPECT_GE(elapsed, 5000.0 / 11520.0);
  EXPECT_LE(log.bytes_per_s, 11520.0 * (1.0 + 1e-9));
}

// ---- flow control ----

// In simulated time (0.5 ms steps, under a character at 19200 7E2): the sender sees DC3 and DC1
// within a step of the controller sending them, on a loaded machine too.
TEST(SimController, XoffAtHighWaterXonAtLowWater) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip, 19200, "7E2");
  auto clock = std::make_shared<ManualClock>();
  cfg.clock = clock;
  Running run(cfg);  // buffer 256, XOFF at 192, XON at 96
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  peer.tick = [&] { return run.step(*clock, 0.0005); };
  const Program prog(40, 1500.0);  // 45 ms a block of some 22 characters: the buffer fills
  ASSERT_TRUE(peer.send_drip(prog.text("\n")));
  ASSERT_TRUE(run.run_to_end(*clock, 0.001, 10.0));
  const SimLog& log = run.stop();
  EXPECT_EQ(log.program_sha256, prog.sha());
  ASSERT_GE(peer.fill_at_xoff.size(), 2U);
  ASSERT_GE(peer.fill_at_xon.size(), 3U);  // ready, then each time the fill fell
  for (std::size_t i = 0; i < peer.fill_at_xoff.size(); ++i) {
    // At most one block started since DC3 was sent at 192; the first DC3 also primed the
    // buffer, and the header lines and the first move left it at once.
    EXPECT_GE(peer.fill_at_xoff[i], i == 0 ? 192 - 60 : 192 - 25);
    EXPECT_LE(peer.fill_at_xoff[i], 192 + 16);
  }
  for (std::size_t i = 1; i < peer.fill_at_xon.size(); ++i) EXPECT_LE(peer.fill_at_xon[i], 96);
  EXPECT_GE(log.max_buffer_fill, 192);
  EXPECT_LE(log.max_buffer_fill, 192 + 16);
  EXPECT_EQ(log.xoff_sent, static_cast<long>(peer.fill_at_xoff.size()));
  EXPECT_TRUE(log.alarms.empty());
}

TEST(SimController, SenderIgnoringXoffOverflows) {
  for (const Flow flow : {Flow::XonXoff, Flow::None}) {
    TempDir dir;
    SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip, 115200, "8N1");
    cfg.line.flow = flow;
    // In simulated time (0.2 ms steps, about 2 characters each): the loop is never late, so the
    // DC3 goes out when due and the sender alone broke the rule.
    auto clock = std::make_shared<ManualClock>();
    cfg.clock = clock;
    Running run(cfg);
    Peer peer(cfg.line.device, run.sim);
    run.start_clock(*clock);
    const Program prog(100, 600.0);  // slow moves: the buffer cannot drain
    peer.send_drip(prog.text("\n"), /*obey=*/false);
    for (int i = 0; i < 20000 && run.sim.progress().alarms == 0; ++i) {
      ASSERT_TRUE(run.step(*clock, 0.0002));
    }
    ASSERT_GT(run.sim.progress().alarms, 0);
    for (int i = 0; i < 20; ++i) ASSERT_TRUE(run.step(*clock, 0.0002));  // the NAK goes out
    peer.listen(0.05);
    const SimLog& log = run.stop();
    EXPECT_EQ(log.xoff_late, 0);
    ASSERT_EQ(log.alarms.size(), 1U);
    EXPECT_EQ(log.alarms[0].code, "overflow");
    EXPECT_GT(log.alarms[0].block, 0);
    EXPECT_EQ(log.max_buffer_fill, 256);
    EXPECT_GT(log.bytes_after_alarm, 0U);
    EXPECT_LE(log.blocks_executed, 2);  // stopped
    ASSERT_GE(peer.received.size(), 2U);
    EXPECT_EQ(peer.received.substr(peer.received.size() - 2), std::string({kXoff, kNak}));
    if (flow == Flow::None) {
      EXPECT_EQ(peer.received, std::string({kXoff, kNak}));  // nothing else on a line without
    }
  }
}

// The controller's loop wakes late (its process starved on a loaded machine) while the line is
// busy, after the sender wrote, no faster than the line, 500 more characters. The characters of
// the burst the loop then reads keep their own arrival times: the executor runs between them,
// and the DC3, due when the fill reaches 192, can only go out late, so what the sender wrote
// meanwhile waits, as the sender would have held it, until DC1. Nothing overflows, with blocks
// that run faster than the line carries them and with blocks much slower. Before, the burst
// landed at one instant, the executor ran after it and the 256-byte buffer overflowed (NAK).
TEST(SimController, LateWakeUpOfTheLoopIsNotBlamedOnTheSender) {
  for (const double feed : {20000.0, 600.0}) {
    SCOPED_TRACE(feed);
    TempDir dir;
    SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip, 38400, "7E2");  // 3490 char/s
    auto clock = std::make_shared<ManualClock>();
    cfg.clock = clock;
    Running run(cfg);
    Peer peer(cfg.line.device, run.sim);
    run.start_clock(*clock);
    const Program prog(40, feed);
    const std::string text = prog.text("\n");
    ASSERT_GT(text.size(), 900U);
    peer.write_all(text.substr(0, 100));
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(run.step(*clock, 0.001));  // the line is busy
    ASSERT_GT(run.sim.progress().bytes_received, 20U);
    peer.write_all(text.substr(100, 500));  // 600 characters in 0.21 s: the line carries 730
    // The clock stands still meanwhile: the kernel moves the characters to the controller's side
    // of the pty (its flip buffer may take a while on a loaded machine), none is read yet.
    std::this_thread::sleep_for(200ms);
    ASSERT_TRUE(run.step(*clock, 0.2));  // the loop wakes 0.2 s late
    peer.tick = [&] { return run.step(*clock, 0.0005); };
    ASSERT_TRUE(peer.send_drip(text.substr(600)));
    ASSERT_TRUE(run.run_to_end(*clock, 0.001, 60.0));
    const SimLog& log = run.stop();
    EXPECT_TRUE(log.alarms.empty()) << log.alarms.front().detail;
    EXPECT_EQ(log.program_sha256, prog.sha());
    EXPECT_EQ(log.blocks_executed, static_cast<long>(prog.blocks.size()));
    EXPECT_EQ(log.xoff_late, 1);
    EXPECT_LE(log.max_buffer_fill, 192 + 16);
  }
}

// ---- underruns ----

// In simulated time (0.2 ms steps): a sender stalled by the machine's load cannot starve it.
TEST(SimController, NoUnderrunWhenFedAhead) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip, 115200, "8N1");
  cfg.buffer_bytes = 2048;
  auto clock = std::make_shared<ManualClock>();
  cfg.clock = clock;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  peer.tick = [&] { return run.step(*clock, 0.0002); };
  const Program prog(40, 6000.0);  // 10 ms a block, some 0.4 s in all
  ASSERT_TRUE(peer.send_drip(prog.text("\n")));
  ASSERT_TRUE(run.run_to_end(*clock, 0.001, 10.0));
  const SimLog& log = run.stop();
  EXPECT_EQ(log.underruns, 0);
  EXPECT_EQ(log.dwell_s, 0.0);
  EXPECT_EQ(log.program_sha256, prog.sha());
  // Back to back: the moves end 10 ms apart (1 mm, or √1.25 mm, at 100 mm/s).
  for (std::size_t i = 1; i < log.moves.size(); ++i) {
    EXPECT_NEAR(log.moves[i].t_s - log.moves[i - 1].t_s, 0.01 * std::sqrt(1.25), 1e-9);
  }
}

// In simulated time (0.2 ms steps): the pause is 0.3 s of the controller's time, and the only one.
TEST(SimController, UnderrunCountedWhenTheSenderPauses) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip, 115200, "8N1");
  cfg.buffer_bytes = 2048;
  auto clock = std::make_shared<ManualClock>();
  cfg.clock = clock;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  peer.tick = [&] { return run.step(*clock, 0.0002); };
  const Program prog(20, 6000.0);
  const std::string text = prog.text("\n");
  const auto cut = text.find("N110");  // after the 10th move
  ASSERT_TRUE(peer.send_drip(text.substr(0, cut)));
  // prime_idle_s (0.5) starts execution, ~0.1 s of moves, then the tool waits for N110.
  for (int i = 0; i < 10000 && run.sim.progress().blocks_executed < 12; ++i) {
    ASSERT_TRUE(run.step(*clock, 0.001));
  }
  ASSERT_EQ(run.sim.progress().blocks_executed, 12);
  for (int i = 0; i < 300; ++i) ASSERT_TRUE(run.step(*clock, 0.001));  // the sender pauses
  ASSERT_TRUE(peer.send_drip(text.substr(cut)));
  ASSERT_TRUE(run.run_to_end(*clock, 0.001, 10.0));
  const SimLog& log = run.stop();
  ASSERT_EQ(log.underruns, 1);
  ASSERT_EQ(log.underrun_events.size(), 1U);
  EXPECT_EQ(log.underrun_events[0].n, 100);
  EXPECT_EQ(log.underrun_events[0].block, 12);  // comment, G21, N10 … N100
  EXPECT_GT(log.underrun_events[0].dwell_s, 0.25);
  EXPECT_DOUBLE_EQ(log.dwell_s, log.underrun_events[0].dwell_s);
  EXPECT_EQ(log.program_sha256, prog.sha());
}

// ---- sequence numbers, lost links, partial lines ----

// A resuming sender that repeats N60 … N80. grbl ignores N numbers and a drip controller runs
// what it receives: the three blocks run twice. Only a controller documented to skip repeated
// sequence numbers (skip_duplicate_n) discards them.
TEST(SimController, RepeatedSequenceNumbersRunAgainUnlessTheControllerSkipsThem) {
  struct Case {
    Protocol protocol;
    bool skip;
  };
  for (const Case k :
       {Case{Protocol::Drip, false}, Case{Protocol::Drip, true}, Case{Protocol::Ack, false}}) {
    SCOPED_TRACE(std::string(k.protocol == Protocol::Drip ? "drip" : "ack") +
                 (k.skip ? " skip" : ""));
    TempDir dir;
    SimControllerConfig cfg = config(dir / "cnc", k.protocol);
    cfg.skip_duplicate_n = k.skip;
    Running run(cfg);
    Peer peer(cfg.line.device, run.sim);
    const Program prog(12, 6000.0, false);
    std::vector<std::string> lines, expect;  // expect: the blocks in the order they must run
    for (std::size_t i = 0; i < prog.blocks.size(); ++i) {
      lines.push_back(prog.blocks[i] + "\n");
      expect.push_back(prog.blocks[i]);
      if (i == 9) {  // a sender resuming from N60 after a lost link
        for (std::size_t j = 7; j <= 9; ++j) {
          lines.push_back(prog.blocks[j] + "\n");
          if (!k.skip) expect.push_back(prog.blocks[j]);
        }
      }
    }
    if (k.protocol == Protocol::Drip) {
      std::string text;
      for (const auto& l : lines) text += l;
      ASSERT_TRUE(peer.send_drip(text));
    } else {
      ASSERT_TRUE(peer.send_ack(lines, cfg.buffer_bytes));
      EXPECT_EQ(peer.replies, std::vector<std::string>(lines.size(), "ok"));
    }
    ASSERT_TRUE(run.wait_end());
    const SimLog& log = run.stop();
    EXPECT_EQ(log.duplicates_discarded, k.skip ? 3 : 0);
    std::vector<std::string> ran;
    for (const SimExecuted& e : log.executed) ran.push_back(e.text);
    EXPECT_EQ(ran, expect);
    EXPECT_EQ(static_cast<int>(log.moves.size()), prog.moves() + (k.skip ? 0 : 3));
  }
}

TEST(SimController, DropLinkUnlinksAndRelinksANewPty) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip, 38400, "8N1");
  cfg.faults.drop_link_after_blocks = 8;
  cfg.faults.down_s = 0.3;
  cfg.skip_duplicate_n = true;  // the resume below repeats blocks
  Running run(cfg);
  const std::string link = cfg.line.device;
  const std::string first_device = run.sim.device();
  const Program prog(20, 6000.0);
  const std::string text = prog.text("\n");
  auto peer = std::make_unique<Peer>(link, run.sim);
  EXPECT_FALSE(peer->send_drip(text));  // the controller hangs up mid-program
  const auto t_drop = Clock::now();
  EXPECT_FALSE(peer->pump());  // hang-up
  EXPECT_FALSE(fs::exists(fs::symlink_status(link)));
  peer.reset();
  ASSERT_TRUE(run.wait([](const SimProgress& p) { return p.link_drops == 1; }));
  std::error_code ec;
  while (!fs::is_symlink(link, ec) && since(t_drop) < 5.0) std::this_thread::sleep_for(2ms);
  ASSERT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(run.sim.progress().blocks_received, 8);  // 8 blocks kept
  // Resume as a drip sender would: from a few blocks back (the controller drops repeats),
  // without the opening %.
  const auto resume = text.find("N40 ");
  Peer again(link, run.sim);
  ASSERT_TRUE(again.send_drip(text.substr(resume)));
  ASSERT_TRUE(run.wait_end());
  const SimLog& log = run.stop();
  EXPECT_EQ(log.link_drops, 1);
  EXPECT_GE(log.duplicates_discarded, 1);
  EXPECT_EQ(log.program_sha256, prog.sha());
  EXPECT_EQ(static_cast<int>(log.moves.size()), prog.moves());
  std::vector<std::string> events;
  std::optional<double> down_t, up_t;
  for (const auto& e : log.link_events) {
    events.push_back(e.event);
    if (e.event == "down") down_t = e.t_s;
    if (e.event == "up") up_t = e.t_s;
  }
  ASSERT_TRUE(down_t && up_t);
  // Down for down_s of the controller's time (the test's own clock would start when it noticed
  // the hang-up, late on a loaded machine).
  EXPECT_GE(*up_t - *down_t, cfg.faults.down_s);
  EXPECT_EQ(log.link_events.front().device, first_device);
}

TEST(SimController, PartialLineOfASenderThatLeftIsDiscarded) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip);
  Running run(cfg);
  const Program prog(6, 6000.0, false);
  const std::string first = prog.blocks[0] + "\n" + prog.blocks[1] + "\n" + "N10 G1 X";
  {
    Peer peer(cfg.line.device, run.sim);
    ASSERT_TRUE(peer.send_drip(first));
  }  // closed mid-block
  ASSERT_TRUE(run.wait([&](const SimProgress& p) { return p.bytes_received >= first.size(); }));
  std::this_thread::sleep_for(20ms);
  Peer peer(cfg.line.device, run.sim);
  std::string rest;
  for (std::size_t i = 2; i < prog.blocks.size(); ++i) rest += prog.blocks[i] + "\n";
  ASSERT_TRUE(peer.send_drip(rest));
  ASSERT_TRUE(run.wait_end());
  const SimLog& log = run.stop();
  EXPECT_EQ(log.partial_lines_discarded, 1);
  EXPECT_TRUE(log.alarms.empty());  // "N10 G1 XN10 G1 X1 …" would be a bad block
  EXPECT_EQ(log.program_sha256, prog.sha());
  EXPECT_EQ(log.sender_connects, 2);
  EXPECT_EQ(log.sender_disconnects, 1);
}

// ---- the acknowledged protocol ----

TEST(SimController, AckAnswersOkAndGrblErrors) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Ack);
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  const std::string long_line =
      "G1 X1.00000000000000000000 Y2.0000000000000000000 (spaces and "
      "comments do not count) Z0.000000000000000000000000000001";
  const std::vector<std::string> lines = {
      "G21 G90\n", "G1 X1 F6000\n", "G91 X1\n",       "G1 X1..2\n", "\n",
      "$H\n",      "G1 Y2\r\n",     long_line + "\n", "M30\n"};
  ASSERT_EQ(grbl_line_chars(long_line), 80);  // one more than grbl keeps
  ASSERT_TRUE(peer.send_ack(lines, cfg.buffer_bytes, 20.0));
  // grbl ends a line at CR and at LF: "G1 Y2\r\n" is a block and an empty line, two oks.
  EXPECT_EQ(peer.replies, (std::vector<std::string>{"ok", "ok", "error:20", "error:1", "ok",
                                                    "error:1", "ok", "ok", "error:11", "ok"}));
  ASSERT_TRUE(run.wait_end());
  const SimLog& log = run.stop();
  EXPECT_EQ(log.blocks_received, 4);
  EXPECT_EQ(log.blocks_rejected, 4);
  ASSERT_EQ(log.errors.size(), 4U);
  EXPECT_EQ(log.errors[3].code, 11);
  EXPECT_EQ(log.errors[0].text, "G91 X1");
  EXPECT_EQ(log.errors[0].line, 3);
  EXPECT_EQ(log.program_sha256, sha256_hex("G21 G90\nG1 X1 F6000\nG1 Y2\nM30\n"));
}

TEST(SimController, AckSenderBreakingCharacterCountingAlarms) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Ack);
  cfg.buffer_bytes = 128;
  cfg.planner_blocks = 4;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  const Program prog(60, 600.0, false);
  std::vector<std::string> lines;
  for (const auto& b : prog.blocks) lines.push_back(b + "\n");
  EXPECT_FALSE(peer.send_ack(lines, 100000));  // counts against a buffer it does not have
  const SimLog& log = run.stop();
  ASSERT_EQ(log.alarms.size(), 1U);
  EXPECT_EQ(log.alarms[0].code, "overflow");
  EXPECT_NE(std::find(peer.replies.begin(), peer.replies.end(), "ALARM:1"), peer.replies.end());
}

// ---- injected faults ----

// In simulated time (0.2 ms steps): how far grbl got before the alarm does not hang on how
// quickly the test's sender is scheduled.
TEST(SimController, InjectedAlarmStopsTheController) {
  for (const Protocol protocol : {Protocol::Drip, Protocol::Ack}) {
    TempDir dir;
    SimControllerConfig cfg = config(dir / "cnc", protocol);
    cfg.faults.alarm_after_blocks = 5;
    auto clock = std::make_shared<ManualClock>();
    cfg.clock = clock;
    Running run(cfg);
    Peer peer(cfg.line.device, run.sim);
    run.start_clock(*clock);
    peer.tick = [&] { return run.step(*clock, 0.0002); };
    const Program prog(20, 6000.0, false);
    std::vector<std::string> lines;
    std::string text;
    for (const auto& b : prog.blocks) {
      lines.push_back(b + "\n");
      text += b + "\n";
    }
    if (protocol == Protocol::Drip) {
      EXPECT_FALSE(peer.send_drip(text));
      EXPECT_TRUE(peer.nak());
      EXPECT_EQ(peer.received.substr(peer.received.size() - 2), std::string({kXoff, kNak}));
    } else {
      EXPECT_FALSE(peer.send_ack(lines, cfg.buffer_bytes));
      const auto alarm = std::find(peer.replies.begin(), peer.replies.end(), "ALARM:9");
      ASSERT_NE(alarm, peer.replies.end());
      EXPECT_EQ(alarm - peer.replies.begin(), 5);  // after the ok of the fifth block
      for (auto r = alarm + 1; r != peer.replies.end(); ++r) EXPECT_EQ(*r, "error:9");
    }
    const SimLog& log = run.stop();
    ASSERT_EQ(log.alarms.size(), 1U);
    EXPECT_EQ(log.alarms[0].code, "injected");
    EXPECT_EQ(log.alarms[0].block, 5);
    EXPECT_EQ(log.alarms[0].n, 30);
    // Drip: never primed, the alarm came first. grbl starts at once: the comment and the setup
    // block took effect, the first 1 mm move (10 ms) at most.
    EXPECT_LE(log.blocks_executed, protocol == Protocol::Drip ? 0 : 3);
  }
}

TEST(SimController, HoldAssertsXoffForItsTime) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip);
  cfg.buffer_bytes = 1024;  // no XOFF from the fill, only the hold's
  cfg.faults.hold_after_blocks = 4;
  cfg.faults.hold_s = 0.4;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  const Program prog(10, 6000.0);
  const auto t0 = Clock::now();
  ASSERT_TRUE(peer.send_drip(prog.text("\n")));
  EXPECT_GE(since(t0), 0.4);
  ASSERT_TRUE(run.wait_end());
  const SimLog& log = run.stop();
  EXPECT_EQ(log.holds, 1);
  EXPECT_EQ(peer.received, std::string({kXon, kXoff, kXon}));
  EXPECT_EQ(log.program_sha256, prog.sha());
}

TEST(SimController, XoffStormLosesNothing) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip, 19200, "7E2");
  cfg.faults.xoff_storm = true;
  cfg.seed = 7;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  const Program prog(60, 6000.0);
  ASSERT_TRUE(peer.send_drip(prog.text("\n")));
  ASSERT_TRUE(run.wait_end());
  const SimLog& log = run.stop();
  EXPECT_GE(log.xoff_storms, 1);
  EXPECT_GE(log.xoff_sent, log.xoff_storms);
  EXPECT_EQ(log.program_sha256, prog.sha());
  EXPECT_TRUE(log.alarms.empty());
  EXPECT_LE(log.max_buffer_fill, cfg.buffer_bytes);
}

// Noise in simulated time (issue 11: on the wall clock a loaded machine starved the loop). The
// controller's clock is a ManualClock moved on 1 ms at a time for 0.4 s; every byte it sends is
// then read, and none of it is DC1, DC3, NAK, SYN, CR or LF (drip), or an ok, error or ALARM
// line (ack).
TEST(SimController, NoiseNeverLooksLikeProtocol) {
  for (const Protocol protocol : {Protocol::Drip, Protocol::Ack}) {
    TempDir dir;
    SimControllerConfig cfg = config(dir / "cnc", protocol);
    cfg.faults.noise_bytes_per_s = 5000;
    auto clock = std::make_shared<ManualClock>();
    cfg.clock = clock;
    Running run(cfg);
    Peer peer(cfg.line.device, run.sim);
    run.start_clock(*clock);
    // The sender's open must be seen before the noise starts (noise goes to a connected sender).
    const auto t_open = Clock::now();
    while (run.sim.log().sender_connects == 0 && since(t_open) < 10.0) {
      ASSERT_TRUE(run.step(*clock, 0.0));
      std::this_thread::sleep_for(1ms);
    }
    for (int i = 0; i < 400; ++i) {
      ASSERT_TRUE(run.step(*clock, 0.001));
      peer.pump();
    }
    // Time stands still now: read until everything sent has arrived.
    const std::size_t lead = protocol == Protocol::Drip ? 1 : 0;  // DC1: ready
    const auto t0 = Clock::now();
    while (since(t0) < 30.0 && peer.received.size() < run.sim.progress().noise_bytes_sent + lead) {
      peer.pump();
      std::this_thread::sleep_for(1ms);
    }
    const SimLog& log = run.stop();
    // Deterministic with the seed: some 2000 bytes in 0.4 s at 5000 bytes/s.
    EXPECT_GT(log.noise_bytes_sent, 1000U);
    EXPECT_LT(log.noise_bytes_sent, 3000U);
    EXPECT_EQ(peer.received.size(), log.noise_bytes_sent + lead);
    if (protocol == Protocol::Drip) {
      ASSERT_FALSE(peer.received.empty());
      EXPECT_EQ(peer.received[0], kXon);  // ready, then noise only
      for (std::size_t i = 1; i < peer.received.size(); ++i) {
        const char c = peer.received[i];
        EXPECT_TRUE(c != kXon && c != kXoff && c != kNak && c != kSyn && c != '\n' && c != '\r')
            << "byte " << i << " = " << static_cast<int>(c);
      }
    } else {
      EXPECT_GT(peer.replies.size(), 20U);
      for (const auto& line : peer.replies) {
        EXPECT_NE(line.rfind("ok", 0), 0U) << line;
        EXPECT_NE(line.rfind("error", 0), 0U) << line;
        EXPECT_NE(line.rfind("ALARM", 0), 0U) << line;
      }
    }
  }
}

// grbl's real-time commands and reset, in simulated time: a 10 mm move at 600 mm/min takes 1 s;
// `?` after 0.25 s reports about 2.5 mm, Run and the planner's count; `!` decelerates the move at
// 100 mm/s² (Hold:1 for v/a = 0.1 s, over v²/2a = 0.5 mm; a `~` then is ignored, as grbl resumes
// only a complete hold), then holds it at rest (Hold:0: the position does not change in 0.5 s);
// `~` resumes, and the move ends 1 s of motion, plus the time at rest, plus the 0.05 s the
// deceleration lost, after it began; 0x18 during the next move aborts it (ALARM:3, banner,
// position kept, the queued block lost). Characters take their time on the wire (87 µs at 115200
// 8N1), so the positions are checked to 0.05 mm (5 ms of motion).
TEST(SimController, GrblStatusHoldResumeAndResetInSimulatedTime) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Ack);
  auto clock = std::make_shared<ManualClock>();
  cfg.clock = clock;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  // Sends a real-time byte and returns the first new reply starting with prefix.
  const auto ask = [&](const std::string& bytes, const std::string& prefix, bool any = false) {
    const std::size_t from = any ? 0 : peer.replies.size();
    peer.write_all(bytes);
    const auto t0 = Clock::now();
    while (since(t0) < 10.0) {
      peer.pump();
      for (std::size_t k = from; k < peer.replies.size(); ++k) {
        if (peer.replies[k].rfind(prefix, 0) == 0) return peer.replies[k];
      }
      run.step(*clock, 0.0001);
    }
    return std::string("(none)");
  };
  const auto x_of = [](const std::string& status) {
    const auto p = status.find("MPos:");
    return p == std::string::npos ? -1.0 : std::stod(status.substr(p + 5));
  };
  peer.write_all("G1 X10 F600\nG1 X20\nG1 X30\n");
  for (int i = 0; i < 250; ++i) ASSERT_TRUE(run.step(*clock, 0.001));  // 0.25 s
  const std::string run1 = ask("?", "<");
  EXPECT_EQ(run1.substr(0, 5), "<Run|") << run1;
  EXPECT_NEAR(x_of(run1), 2.5, 0.05) << run1;
  EXPECT_NE(run1.find("|Bf:12,128|"), std::string::npos) << run1;  // 3 moves of 15, buffer empty
  EXPECT_NE(run1.find("|FS:600,0"), std::string::npos) << run1;    // feed, spindle stopped
  EXPECT_NE(run1.find("|WCO:0.000,0.000,0.000"), std::string::npos) << run1;  // the first report
  peer.write_all("!");  // nothing answers a hold: the status below is read after it
  const std::string slowing = ask("?", "<");
  EXPECT_EQ(slowing.substr(0, 8), "<Hold:1|") << slowing;
  peer.write_all("~");  // ignored: the hold is not complete
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(run.step(*clock, 0.001));  // v/a = 0.1 s
  const std::string held = ask("?", "<");
  for (int i = 0; i < 500; ++i) ASSERT_TRUE(run.step(*clock, 0.001));  // held 0.5 s
  const std::string held2 = ask("?", "<");
  EXPECT_EQ(held.substr(0, 8), "<Hold:0|") << held;
  EXPECT_NEAR(x_of(held), x_of(run1) + 0.5, 0.05) << held;  // v²/2a further
  EXPECT_GT(x_of(held), x_of(slowing)) << slowing;
  EXPECT_EQ(x_of(held), x_of(held2)) << held2;
  EXPECT_NE(held2.find("|FS:0,0"), std::string::npos) << held2;
  peer.write_all("~");
  for (int i = 0; i < 800; ++i) ASSERT_TRUE(run.step(*clock, 0.001));  // to X10, then on
  const std::string run2 = ask("?", "<");
  EXPECT_EQ(run2.substr(0, 5), "<Run|") << run2;
  EXPECT_GT(x_of(run2), 10.0) << run2;
  EXPECT_EQ(ask(std::string(1, kGrblReset), "ALARM"), "ALARM:3");
  EXPECT_EQ(ask("", "Grbl", true), kGrblBanner);
  const SimLog& log = run.stop();
  ASSERT_EQ(log.executed.size(), 1U);
  EXPECT_EQ(log.executed[0].text, "G1 X10 F600");
  // 1 s of motion, the 0.05 s the deceleration lost, and the time at rest (0.5 s and the
  // question's few steps).
  EXPECT_NEAR(log.executed[0].t_s, 1.55, 0.01);
  ASSERT_EQ(log.resets.size(), 1U);
  EXPECT_TRUE(log.resets[0].in_motion);
  EXPECT_EQ(log.resets[0].aborted, "G1 X20");
  EXPECT_EQ(log.resets[0].blocks_lost, 1);                   // G1 X30
  EXPECT_NEAR(log.resets[0].position[0], x_of(run2), 0.05);  // kept where it stopped
  // The last report before the reset (run2, past X10) was sent with G1 X10 executed: what a
  // sender could know then.
  EXPECT_EQ(log.resets[0].executed_at_last_report, 1);
  EXPECT_EQ(to_json(log)["resets"][0]["executed_at_last_report"], 1);
  EXPECT_EQ(log.feed_holds, 1);
  EXPECT_EQ(log.cycle_starts, 1);  // the `~` during Hold:1 did nothing
}

// A grbl-mode exchange over the pty, in simulated time: writes `bytes` and steps the clock until
// a new reply starts with `prefix` (or 10 s of wall time pass); returns it, or "(none)".
std::string grbl_ask(Peer& peer, Running& run, ManualClock& clock, const std::string& bytes,
                     const std::string& prefix) {
  const std::size_t from = peer.replies.size();
  peer.write_all(bytes);
  const auto t0 = Clock::now();
  while (since(t0) < 10.0) {
    peer.pump();
    for (std::size_t k = from; k < peer.replies.size(); ++k) {
      if (peer.replies[k].rfind(prefix, 0) == 0) return peer.replies[k];
    }
    run.step(clock, 0.0005);
  }
  return "(none)";
}

// A hold that arrives when a move's time is over but the controller's loop has not yet retired
// it (a loaded machine: the loop runs late) holds where that move ended. The model once answered
// the hold's position before it knew it: MPos 0,0,0 while the tool stood at the move's end, and
// ncd's ending then rightly refused to move (link/held_position.hpp). Each round moves the clock
// past the move's end while a `!` is on the wire, so the loop takes the `!` before it retires
// the move.
TEST(SimController, GrblHoldAfterAMoveEndedButBeforeItIsRetiredHoldsAtItsEnd) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Ack);
  auto clock = std::make_shared<ManualClock>();
  cfg.clock = clock;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  const auto x_of = [](const std::string& status) {
    const auto p = status.find("MPos:");
    return p == std::string::npos ? -1.0 : std::stod(status.substr(p + 5));
  };
  for (int round = 1; round <= 10; ++round) {
    const std::string move = "G1 X" + std::to_string(round) + " F600\n";  // 0.1 s
    EXPECT_EQ(grbl_ask(peer, run, *clock, move, "ok"), "ok") << "round " << round;
    ASSERT_TRUE(run.step(*clock, 0.01));  // the move executes
    // The `!` goes on the wire; the loop sees it start and waits one character's time, in the
    // controller's clock, to take it. Then the clock passes the move's end: the loop takes the
    // `!` before it retires the move.
    peer.write_all("!");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    clock->advance(0.5);
    const std::string held = grbl_ask(peer, run, *clock, "?", "<");
    EXPECT_EQ(held.substr(0, 8), "<Hold:0|") << "round " << round << ": " << held;
    EXPECT_NEAR(x_of(held), round, 1e-9) << "round " << round << ": " << held;
    peer.write_all("~");
    for (int i = 0; i < 20; ++i) ASSERT_TRUE(run.step(*clock, 0.001));
  }
  const SimLog& log = run.stop();
  EXPECT_EQ(log.feed_holds, 10);
  EXPECT_TRUE(log.resets.empty());
  ASSERT_FALSE(log.moves.empty());
  EXPECT_NEAR(log.moves.back().p[0], 10.0, 1e-9);
}

// grbl's safe halt (its manual: feed hold, wait for Hold:0, then reset) against a reset during
// the hold's deceleration. A reset in Hold:1 is a reset in motion: ALARM:3, the lock (every
// g-code line error:9, `?` Alarm) until `$X`, which answers [MSG:Caution: Unlocked] and ok. The
// reset also cleared the parser (F is undefined: error:22). A reset once the hold is complete
// (Hold:0) raises nothing and leaves grbl Idle. `$10` sets the status mask: 1 has no Bf:, 0
// reports WPos; `$10=` while moving is error:8. While held at rest grbl reads no line (its
// protocol loop is suspended): a line sent then is answered after `~`.
TEST(SimController, GrblResetDuringTheHoldAlarmsAfterItDoesNot) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Ack);
  auto clock = std::make_shared<ManualClock>();
  cfg.clock = clock;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  const auto ask = [&](const std::string& bytes, const std::string& prefix) {
    return grbl_ask(peer, run, *clock, bytes, prefix);
  };
  const auto wait_state = [&](const std::string& state) {
    for (int i = 0; i < 400; ++i) {
      const std::string st = ask("?", "<");
      if (st.rfind("<" + state, 0) == 0) return st;
      for (int k = 0; k < 10; ++k) run.step(*clock, 0.001);
    }
    return std::string("(never ") + state + ")";
  };
  EXPECT_EQ(ask("G1 X10 F600\nG1 X20\n", "ok"), "ok");
  for (int i = 0; i < 200; ++i) ASSERT_TRUE(run.step(*clock, 0.001));
  // `!` and 0x18 at once, as ncd did: the reset comes while the move decelerates.
  EXPECT_EQ(ask(std::string("!") + kGrblReset, "ALARM"), "ALARM:3");
  // The message follows ALARM:3 on the wire: wait for it (a loaded machine delivers it later).
  const auto saw = [&](const std::string& line) {
    const auto t0 = Clock::now();
    while (since(t0) < 10.0) {
      peer.pump();
      if (std::find(peer.replies.begin(), peer.replies.end(), line) != peer.replies.end()) {
        return true;
      }
      std::this_thread::sleep_for(1ms);
    }
    return false;
  };
  EXPECT_TRUE(saw("[MSG:'$H'|'$X' to unlock]"));
  EXPECT_EQ(wait_state("Alarm").substr(0, 7), "<Alarm|");
  EXPECT_EQ(ask("G1 X1 F600\n", "error"), "error:9");  // locked
  EXPECT_EQ(ask("$X\n", "[MSG"), "[MSG:Caution: Unlocked]");
  EXPECT_EQ(wait_state("Idle").substr(0, 6), "<Idle|");
  EXPECT_EQ(ask("G1 X5\n", "error"), "error:22");  // the reset cleared F
  EXPECT_EQ(ask("G1 X5 F600\n", "ok"), "ok");
  EXPECT_EQ(ask("$10=2\n", "error"), "error:8");  // not while moving
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(run.step(*clock, 0.001));
  peer.write_all("!");
  const std::string at_rest = wait_state("Hold:0");
  EXPECT_EQ(at_rest.substr(0, 8), "<Hold:0|") << at_rest;
  peer.write_all("G1 X6\n");  // not read while held at rest
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(run.step(*clock, 0.001));
  peer.pump();
  // G1 X10, G1 X20, $X, G1 X5 F600; not G1 X6
  EXPECT_EQ(std::count(peer.replies.begin(), peer.replies.end(), "ok"), 4);
  peer.write_all(std::string(1, kGrblReset));  // at rest: no alarm
  EXPECT_EQ(ask("", "Grbl"), kGrblBanner);
  EXPECT_EQ(wait_state("Idle").substr(0, 6), "<Idle|");
  EXPECT_EQ(ask("$10=1\n", "ok"), "ok");
  const std::string mpos_only = ask("?", "<");
  EXPECT_NE(mpos_only.find("|MPos:"), std::string::npos) << mpos_only;
  EXPECT_EQ(mpos_only.find("|Bf:"), std::string::npos) << mpos_only;
  EXPECT_EQ(ask("$10=0\n", "ok"), "ok");
  const std::string wpos = ask("?", "<");
  EXPECT_NE(wpos.find("|WPos:"), std::string::npos) << wpos;
  const SimLog& log = run.stop();
  ASSERT_EQ(log.resets.size(), 2U);
  EXPECT_TRUE(log.resets[0].in_motion);     // during Hold:1
  EXPECT_FALSE(log.resets[1].in_motion);    // at rest in Hold:0
  EXPECT_EQ(log.resets[1].blocks_lost, 1);  // G1 X6, still in the receive buffer
  EXPECT_EQ(log.unlocks, 1);
  for (const SimExecuted& e : log.executed) EXPECT_NE(e.text, "G1 X6");  // lost in the reset
}

// A restart at power-up with the USB link gone meanwhile (restart_after_blocks): the banner goes
// out while the port is closed, so a sender reopening it hears nothing; the controller is Idle,
// its position restarted at 0, its spindle stopped (FS:…,0), its queue and modes lost.
TEST(SimController, GrblRestartBannerIsLostWhileThePortIsClosed) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Ack);
  cfg.dialect = Dialect::grbl;
  cfg.faults.restart_after_blocks = 4;
  cfg.faults.down_s = 0.3;
  auto clock = std::make_shared<ManualClock>();
  cfg.clock = clock;
  Running run(cfg);
  run.start_clock(*clock);
  {
    Peer peer(cfg.line.device, run.sim);
    peer.write_all("S1000 M3\nG1 X10 F600\nG1 X20\nG1 X30\nG1 X40\n");
    for (int i = 0; i < 200 && peer.pump(); ++i) ASSERT_TRUE(run.step(*clock, 0.001));
    EXPECT_FALSE(peer.pump());  // hung up
  }
  for (int i = 0; i < 400; ++i) ASSERT_TRUE(run.step(*clock, 0.001));  // the link is back
  ASSERT_TRUE(fs::is_symlink(cfg.line.device));
  Peer peer(cfg.line.device, run.sim);
  for (int i = 0; i < 200; ++i) ASSERT_TRUE(run.step(*clock, 0.001));
  peer.pump();
  EXPECT_TRUE(peer.replies.empty()) << peer.replies.front();  // no banner
  const std::string st = grbl_ask(peer, run, *clock, "?", "<");
  EXPECT_EQ(st.substr(0, 30), "<Idle|MPos:0.000,0.000,0.000|B") << st;
  EXPECT_NE(st.find("|FS:0,0"), std::string::npos) << st;
  const SimLog& log = run.stop();
  ASSERT_EQ(log.resets.size(), 1U);
  EXPECT_EQ(log.resets[0].cause, "power_cycle");
  EXPECT_FALSE(log.resets[0].in_motion);  // no ALARM:3: the board lost its power
  EXPECT_GT(log.resets[0].position[0], 0.0);
  EXPECT_EQ(log.banners_sent, 1);
  EXPECT_EQ(log.banners_lost, 1);
  EXPECT_EQ(log.link_drops, 1);
  bool spindle_stopped = false;
  for (const SimEvent& e : log.events)
    spindle_stopped = spindle_stopped || e.kind == "spindle_stop";
  EXPECT_TRUE(spindle_stopped);
}

TEST(SimController, ExitAtEndReturnsAfterTheProgram) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Drip);
  cfg.exit_at_end = true;
  Running run(cfg);
  {
    Peer peer(cfg.line.device, run.sim);
    ASSERT_TRUE(peer.send_drip(Program(5, 6000.0).text("\n")));
  }
  const auto t0 = Clock::now();
  while (!run.done() && since(t0) < 5.0) std::this_thread::sleep_for(1ms);
  ASSERT_TRUE(run.done());  // returned on its own
  const SimLog& log = run.stop();
  EXPECT_EQ(log.stop_reason, "program_end");
  EXPECT_TRUE(log.program_end_executed);
  EXPECT_FALSE(fs::is_symlink(cfg.line.device));
}

// ---- the grbl dialect and the events ----

// Streams lines with grbl's character counting (each line with LF) while the controller's clock
// advances dt_s a turn; returns the answers (ok, error:N, ALARM:N) in order. Stops at an ALARM,
// when every line is answered, or after max_sim_s of controller time.
std::vector<std::string> stream_grbl(Peer& peer, Running& run, ManualClock& clock,
                                     const std::vector<std::string>& lines, int buffer, double dt_s,
                                     double max_sim_s) {
  std::vector<std::string> answers;
  std::deque<int> sizes;
  int used = 0;
  std::size_t next = 0, seen = peer.replies.size();
  for (double t = 0.0; (next < lines.size() || !sizes.empty()) && t < max_sim_s; t += dt_s) {
    peer.pump();
    while (seen < peer.replies.size()) {
      const std::string& r = peer.replies[seen++];
      if (r == "ok" || r.rfind("error:", 0) == 0) {
        answers.push_back(r);
        if (!sizes.empty()) {
          used -= sizes.front();
          sizes.pop_front();
        }
      } else if (r.rfind("ALARM", 0) == 0) {
        answers.push_back(r);
        return answers;
      }
    }
    while (next < lines.size() && used + static_cast<int>(lines[next].size()) + 1 <= buffer) {
      peer.write_all(lines[next] + "\n");
      used += static_cast<int>(lines[next].size()) + 1;
      sizes.push_back(static_cast<int>(lines[next].size()) + 1);
      ++next;
    }
    if (!run.step(clock, dt_s)) break;
  }
  return answers;
}

SimControllerConfig grbl_config(const fs::path& link, const std::shared_ptr<ManualClock>& clock) {
  SimControllerConfig cfg = config(link, Protocol::Ack);
  cfg.dialect = Dialect::grbl;
  cfg.clock = clock;
  return cfg;
}

const SimEvent* find_event(const SimLog& log, const std::string& kind) {
  for (const SimEvent& e : log.events) {
    if (e.kind == kind) return &e;
  }
  return nullptr;
}

// A whole program with spindle, dwell, a line, an arc, spindle stop and program end: grbl mode
// answers ok on every line, and the events and moves run at the times the program implies
// (10 mm at 600 mm/min: 1 s; a half circle of radius 5 at 600 mm/min: 5π/10 s).
TEST(SimGrblDialect, WholeProgramOkOnEveryLineWithTimedEvents) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  const SimControllerConfig cfg = grbl_config(dir / "cnc", clock);
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  const std::vector<std::string> program = {
      "G21 G90 G94", "G17 (plane) ; header", "M3 S12000", "G4 P0.5",
      "G1 X10 F600", "G2 X20 Y0 I5 J0",      "M5",        "G0 Z5",
      "M2"};
  const auto answers = stream_grbl(peer, run, *clock, program, cfg.buffer_bytes, 0.002, 20.0);
  EXPECT_EQ(answers, std::vector<std::string>(program.size(), "ok"));
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(run.step(*clock, 0.002));
  ASSERT_TRUE(run.wait_end());
  const SimLog& log = run.stop();
  EXPECT_TRUE(log.alarms.empty());
  EXPECT_TRUE(log.errors.empty());
  const SimEvent* speed = find_event(log, "speed");
  const SimEvent* cw = find_event(log, "spindle_cw");
  const SimEvent* dwell = find_event(log, "dwell");
  const SimEvent* stop = find_event(log, "spindle_stop");
  const SimEvent* end = find_event(log, "program_end");
  ASSERT_TRUE(speed && cw && dwell && stop && end);
  EXPECT_EQ(speed->value, 12000.0);
  EXPECT_EQ(cw->t_s, speed->t_s);
  EXPECT_EQ(dwell->value, 0.5);
  EXPECT_GE(dwell->t_s, cw->t_s);
  ASSERT_EQ(log.moves.size(), 3U);
  EXPECT_NEAR(log.moves[0].t_s, dwell->t_s + 0.5 + 1.0, 1e-9);
  EXPECT_NEAR(log.moves[1].t_s, log.moves[0].t_s + 5.0 * M_PI / 10.0, 1e-9);
  EXPECT_EQ(log.moves[1].g, 2);
  EXPECT_NEAR(stop->t_s, log.moves[1].t_s, 1e-9);  // M5 waits for the arc
  EXPECT_NEAR(log.moves[2].t_s, stop->t_s + 5.0 / (5000.0 / 60.0), 1e-9);
  EXPECT_NEAR(end->t_s, log.moves[2].t_s, 1e-9);
  EXPECT_NEAR(log.path_length_mm, 10.0 + 5.0 * M_PI + 5.0, 1e-9);
  // Only one spindle stop: M2 finds the spindle already stopped.
  EXPECT_EQ(std::count_if(log.events.begin(), log.events.end(),
                          [](const SimEvent& e) { return e.kind == "spindle_stop"; }),
            1);
  const auto json_out = to_json(log);
  EXPECT_EQ(json_out["events"].size(), log.events.size());
  EXPECT_EQ(json_out["settings"]["dialect"], "grbl");
  std::printf("grbl program: %zu lines ok, %zu events, end at %.4f s (simulated)\n", answers.size(),
              log.events.size(), end->t_s);
}

// A feed move with the spindle stopped: the machine-safety alarm (grbl itself would move).
TEST(SimGrblDialect, FeedMoveWithTheSpindleStoppedAlarms) {
  for (const bool safety : {true, false}) {
    TempDir dir;
    auto clock = std::make_shared<ManualClock>();
    SimControllerConfig cfg = grbl_config(dir / "cnc", clock);
    cfg.machine_safety = safety;
    Running run(cfg);
    Peer peer(cfg.line.device, run.sim);
    run.start_clock(*clock);
    const std::vector<std::string> program = {"G21 G90", "G0 X1", "G1 X10 F600", "M2"};
    const auto answers = stream_grbl(peer, run, *clock, program, cfg.buffer_bytes, 0.002, 5.0);
    const SimLog& log = run.stop();
    if (safety) {
      EXPECT_EQ(answers, (std::vector<std::string>{"ok", "ok", "ALARM:1"}));
      ASSERT_EQ(log.alarms.size(), 1U);
      EXPECT_EQ(log.alarms[0].code, "spindle_stopped");
      EXPECT_NE(log.alarms[0].detail.find("G1 X10 F600"), std::string::npos);
      EXPECT_LE(log.moves.size(), 1U);  // the rapid at most; never the cut
      for (const SimMove& m : log.moves) EXPECT_EQ(m.g, 0);
    } else {
      EXPECT_EQ(answers, std::vector<std::string>(4, "ok"));
      EXPECT_TRUE(log.alarms.empty());
    }
  }
}

// M0 holds the program until cycle start (`~` on the grbl link); its ok comes after the resume,
// as grbl's suspend loop in gc_execute_line does.
TEST(SimGrblDialect, M0WaitsForCycleStart) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  const SimControllerConfig cfg = grbl_config(dir / "cnc", clock);
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  const std::vector<std::string> program = {"M3 S1000", "G1 X5 F600", "M0", "G1 X10", "M30"};
  auto answers = stream_grbl(peer, run, *clock, program, cfg.buffer_bytes, 0.002, 3.0);
  EXPECT_EQ(answers, (std::vector<std::string>{"ok", "ok"}));  // M0 unanswered, the rest waits
  EXPECT_EQ(run.sim.progress().blocks_executed, 2);
  const std::size_t before = peer.replies.size();
  peer.write_all("?");
  for (int i = 0; i < 50 && peer.replies.size() == before; ++i) {
    ASSERT_TRUE(run.step(*clock, 0.001));
    peer.pump();
  }
  ASSERT_GT(peer.replies.size(), before);
  EXPECT_EQ(peer.replies.back().substr(0, 8), "<Hold:0|") << peer.replies.back();
  peer.write_all("~");
  for (int i = 0; i < 1000 && !run.sim.progress().program_end_executed; ++i) {
    ASSERT_TRUE(run.step(*clock, 0.002));
    peer.pump();
  }
  const SimLog& log = run.stop();
  const SimEvent* pause = find_event(log, "pause");
  const SimEvent* resume = find_event(log, "resume");
  ASSERT_TRUE(pause && resume);
  ASSERT_EQ(log.moves.size(), 2U);
  EXPECT_NEAR(pause->t_s, log.moves[0].t_s, 1e-9);  // stops when X5 is reached
  EXPECT_GT(resume->t_s - pause->t_s, 2.0);         // held while nobody pressed start
  EXPECT_NEAR(log.moves[1].t_s, resume->t_s + 0.5, 1e-9);
  EXPECT_EQ(log.cycle_starts, 1);
  EXPECT_TRUE(log.program_end_executed);
}

// A drip (iso) controller: M6 takes the configured tool-change time, M0 waits for the control's
// cycle-start button (SimController::cycle_start), and a line the iso dialect refuses alarms.
TEST(SimIsoDialect, ToolChangeTimeAndCycleStartButton) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  SimControllerConfig cfg = config(dir / "cnc");
  cfg.dialect = Dialect::iso;
  cfg.clock = clock;
  cfg.tool_change_s = 4.0;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  peer.write_all("%\nN1 T2 M6\nN2 S8000 M3\nN3 G1 X6 F600\nN4 M0\nN5 G1 X0\nN6 M30\n%\n");
  for (int i = 0; i < 3000 && run.sim.progress().blocks_executed < 4; ++i) {
    ASSERT_TRUE(run.step(*clock, 0.005));
  }
  for (int i = 0; i < 200; ++i) ASSERT_TRUE(run.step(*clock, 0.005));  // 1 s stopped
  EXPECT_EQ(run.sim.progress().blocks_executed, 3);                    // N4 holds
  run.sim.cycle_start();
  for (int i = 0; i < 1000 && !run.sim.progress().program_end_executed; ++i) {
    ASSERT_TRUE(run.step(*clock, 0.005));
  }
  const SimLog& log = run.stop();
  EXPECT_TRUE(log.alarms.empty());
  const SimEvent* change = find_event(log, "tool_change");
  const SimEvent* cw = find_event(log, "spindle_cw");
  const SimEvent* pause = find_event(log, "pause");
  const SimEvent* resume = find_event(log, "resume");
  ASSERT_TRUE(change && cw && pause && resume);
  EXPECT_EQ(change->value, 4.0);
  EXPECT_NEAR(cw->t_s, change->t_s + 4.0, 1e-9);  // N2 starts when the change is over
  ASSERT_EQ(log.moves.size(), 2U);
  EXPECT_NEAR(log.moves[0].t_s, cw->t_s + 0.6, 1e-9);
  EXPECT_NEAR(pause->t_s, log.moves[0].t_s, 1e-9);
  EXPECT_NEAR(log.moves[1].t_s, resume->t_s + 0.6, 1e-9);
  EXPECT_TRUE(find_event(log, "program_end"));
}

TEST(SimIsoDialect, ARefusedLineAlarms) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc");
  cfg.dialect = Dialect::iso;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  peer.send_drip("%\nN1 S100 M3\nN2 #1=5\nN3 M30\n%\n");  // false: the NAK of the alarm
  ASSERT_TRUE(run.wait([](const SimProgress& p) { return p.alarms > 0; }));
  const SimLog& log = run.stop();
  ASSERT_EQ(log.alarms.size(), 1U);
  EXPECT_EQ(log.alarms[0].code, "bad_block");
  EXPECT_NE(log.alarms[0].detail.find("'#'"), std::string::npos) << log.alarms[0].detail;
}

// One random line of G-code, valid or not: words from grbl's set and outside it, numbers well
// and badly formed, comments, spaces and case. Dwell, feed and coordinates are kept small so
// the stream runs quickly (coordinates within ±2, feeds of 3000 to 6000); G38.2/G38.4 (the
// simulation's probe never touches: an alarm) and M0 (a stop waiting for cycle start) are left out.
std::string random_line(std::mt19937_64& rng) {
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  static const std::vector<std::string> codes = {
      "G0",  "G1",    "G2",    "G3",    "G4",    "G10",   "G17", "G18", "G19",   "G20", "G21",
      "G28", "G28.1", "G30",   "G30.1", "G38.3", "G38.1", "G40", "G43", "G43.1", "G49", "G53",
      "G54", "G55",   "G59.1", "G61",   "G61.1", "G64",   "G80", "G90", "G90.1", "G91", "G91.1",
      "G92", "G92.1", "G93",   "G94",   "G1.5",  "G5.2",  "M1",  "M2",  "M3",    "M4",  "M5",
      "M6",  "M7",    "M8",    "M9",    "M30",   "M3.5",  "M56", "M99"};
  static const std::string letters = "XYZXYZXYZXYZIJKFFFPRSTLNAQ";
  std::string s;
  const int words = 1 + pick(5);
  for (int w = 0; w < words; ++w) {
    if (pick(4) == 0) {
      s += codes[static_cast<std::size_t>(pick(static_cast<int>(codes.size())))];
    } else {
      const char letter = letters[static_cast<std::size_t>(pick(static_cast<int>(letters.size())))];
      s += letter;
      double v = std::uniform_real_distribution<>(-2.0, 2.0)(rng);
      if (letter == 'F') v = std::uniform_real_distribution<>(3000.0, 6000.0)(rng);
      if (letter == 'P') v = pick(3) == 0 ? -1.0 : pick(8);
      if (letter == 'L') v = pick(3) == 0 ? 20 : 2 + pick(2);
      if (letter == 'N') v = pick(4) == 0 ? 10000001 : pick(1000);
      if (letter == 'T') v = pick(250) + (pick(5) == 0 ? 100 : 0);
      if (letter == 'S') v = pick(20000) - (pick(10) == 0 ? 20000 : 0);
      if (letter == 'P' && v > 0) v = 0.01;  // dwells of 10 ms
      const int form = pick(40);
      if (form == 0) {
        s += "1..2";
      } else if (form == 1) {
        s += ".";
      } else if (form == 2) {
        s += "-";
      } else {
        char buf[32];
        std::snprintf(buf, sizeof buf, form < 20 ? "%.0f" : "%.3f", v);
        s += buf;
      }
    }
    const int sep = pick(10);
    if (sep < 3) s += ' ';
    if (sep == 3) s += "(c)";
  }
  if (pick(10) == 0) s += " ; comment";
  if (pick(15) == 0) {
    s += "N";  // N0000…: a long line whose numbers stay small
    while (s.size() < 78 + static_cast<std::size_t>(pick(5))) s += '0';
  }
  if (pick(20) == 0) s = "#" + s;
  if (pick(20) == 0) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return s;
}

// The sender's pre-check (check_line over the program, as DncSender and check_program_file run
// it) and the grbl-mode controller's answer over a real pty agree on every line: the same
// error number, or ok. Lines after an M2/M30 too (grbl reads on).
TEST(SimGrblDialect, RandomLinesPrecheckAndControllerAgree) {
  const char* forced = std::getenv("NCD_SEED");  // to replay a failure
  const std::uint64_t seed = forced ? std::stoull(forced) : std::random_device{}();
  std::printf("random grbl lines: seed %llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  std::vector<std::string> lines;
  std::vector<int> expected;
  DialectState state;
  for (int i = 0; i < 500; ++i) {
    std::string line = random_line(rng);
    if (line.size() > 120) line.resize(120);  // raw lines within grbl's 128-byte buffer
    const auto v = check_line(Dialect::grbl, line, state);
    lines.push_back(line);
    expected.push_back(v ? v->grbl_error : 0);
  }
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  SimControllerConfig cfg = grbl_config(dir / "cnc", clock);
  cfg.machine_safety = false;  // verdicts only; the safety alarm is an execution matter
  cfg.rapid_mm_per_min = 20000.0;
  Running run(cfg);
  Peer peer(cfg.line.device, run.sim);
  run.start_clock(*clock);
  const auto answers = stream_grbl(peer, run, *clock, lines, cfg.buffer_bytes, 0.05, 5000.0);
  ASSERT_EQ(answers.size(), lines.size())
      << "seed " << seed
      << "; first unanswered line: " << (answers.size() < lines.size() ? lines[answers.size()] : "")
      << "; executed " << run.sim.progress().blocks_executed << ", t " << run.sim.progress().t_s;
  int errors = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string want = expected[i] == 0 ? "ok" : "error:" + std::to_string(expected[i]);
    EXPECT_EQ(answers[i], want) << "seed " << seed << ", line " << i + 1 << ": " << lines[i];
    errors += expected[i] != 0;
  }
  // The whole-file check names the first refused line.
  std::ofstream(dir / "p.nc") << [&] {
    std::string text;
    for (const auto& l : lines) text += l + "\n";
    return text;
  }();
  const auto first = check_program_file((dir / "p.nc").string(), Dialect::grbl);
  const auto it = std::find_if(expected.begin(), expected.end(), [](int e) { return e != 0; });
  if (it == expected.end()) {
    EXPECT_FALSE(first);
  } else {
    ASSERT_TRUE(first);
    EXPECT_EQ(first->line, it - expected.begin() + 1);
    EXPECT_EQ(first->grbl_error, *it);
  }
  std::printf("random grbl lines: %zu lines (%d refused, %zu taken), verdicts compared\n",
              lines.size(), errors, lines.size() - static_cast<std::size_t>(errors));
  run.stop();
}

// `ncd stream --dialect grbl` refuses the issue's program (G64 P0.0100 on line 3) before it
// opens the port: exit 2, the line and the word named, not one byte on the controller's wire.
TEST(SimGrblDialect, StreamRefusesBeforeTheFirstByte) {
  TempDir dir;
  SimControllerConfig cfg = config(dir / "cnc", Protocol::Ack);
  cfg.dialect = Dialect::grbl;
  Running run(cfg);
  const fs::path program = dir / "chamfer.ngc";
  std::ofstream(program) << "G21 G90 G94\nG17\nG64 P0.0100\nM3 S12000\nG1 X1 F100\nM2\n";
  const fs::path err = dir / "stderr.txt";
  const std::string command = std::string(NCD_EXE) + " stream " + program.string() + " --port " +
                              cfg.line.device + " --protocol ack --baud 115200 --frame 8N1 " +
                              "--flow none --dialect grbl --no-journal -q 2>" + err.string();
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
  std::ifstream in(err);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("line 3"), std::string::npos) << text;
  EXPECT_NE(text.find("'G64'"), std::string::npos) << text;
  EXPECT_NE(text.find("error:20"), std::string::npos) << text;
  std::this_thread::sleep_for(100ms);
  const SimLog& log = run.stop();
  EXPECT_EQ(log.bytes_received, 0U);
  EXPECT_EQ(log.sender_connects, 0);
  // The same program without G64 streams: the check passes it.
  std::ofstream(program) << "G21 G90 G94\nG17\nM3 S12000\nG1 X1 F100\nM2\n";
  EXPECT_FALSE(check_program_file(program.string(), Dialect::grbl));
  // iso refuses a macro variable, naming its line.
  std::ofstream(program) << "%\nN1 G0 X0\nN2 #1=3\n%\n";
  const auto v = check_program_file(program.string(), Dialect::iso);
  ASSERT_TRUE(v);
  EXPECT_EQ(v->line, 3);
}

}  // namespace
}  // namespace ncd::comms
