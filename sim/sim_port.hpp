// The simulated controller's side of the link (the I/O the model of sim_controller.cpp leaves
// out): the pseudo-terminal the sender opens (link/pty.hpp) and the pipe that wakes the
// controller's loop. It decides nothing: the model (SimController::Impl) chooses when and how
// many bytes to take off the line (at the line's rate, in its own time), what to send, and
// what a connection or a hang-up means; this class reads, writes, flushes and waits when told.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "link/pty.hpp"

namespace ncd::comms {

class SimPort {
 public:
  // Creates the pty and links it at `link` (Pty's errors), then the wake pipe
  // (std::system_error).
  explicit SimPort(std::string link);
  ~SimPort();
  SimPort(const SimPort&) = delete;
  SimPort& operator=(const SimPort&) = delete;

  // The pty: a new pair at the same link (a link restored), or closed (a link drop, the end).
  void open() { pty_.open(); }
  void close() { pty_.close(); }
  bool is_open() const { return pty_.is_open(); }
  // The slave the link points at now; empty when closed.
  const std::string& device() const { return pty_.device(); }
  // The opens and closes of the slave by senders since the last call, oldest first.
  std::vector<Pty::SlaveEvent> take_slave_events() { return pty_.take_slave_events(); }

  // Reads up to `n` of the bytes the sender wrote into `to`, without waiting; 0 when none is
  // waiting (or the pty is closed).
  std::size_t read(char* to, std::size_t n);
  // Writes what the kernel takes of `bytes` now: how many, or nullopt when the pty failed
  // (what was not written is then lost).
  std::optional<std::size_t> write(std::string_view bytes);
  // The bytes the sender wrote that wait in the kernel, readable now (FIONREAD); 0 when not
  // known.
  std::size_t waiting() const;
  // Throws away what the sender wrote and the controller has not read.
  void flush_input();

  // Waits up to wait_s for a wake(), a sender opening or closing the slave, the master
  // readable (when want_read) or writable (when want_write); returns whether it is readable.
  bool wait(double wait_s, bool want_read, bool want_write);
  // Makes wait() return now. Async-signal-safe; callable from any thread.
  void wake() noexcept;

 private:
  Pty pty_;
  std::array<int, 2> wake_{-1, -1};
};

}  // namespace ncd::comms
