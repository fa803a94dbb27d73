// The RS-232 link on libserial: opens a serial device (or a pseudo-terminal standing in for
// one) with the machine's line settings, then gives non-blocking reads and writes, a wait on
// the descriptor, the kernel's output queue (TIOCOUTQ) and the CTS line where the device has
// one.
//
// Software flow control is done by the sender, not by the kernel: IXON is left off so DC1 and
// DC3 reach the sender, which then knows how long the controller held it and can report it.
// RTS/CTS is left to the driver (CRTSCTS), which stops the UART within about 2 characters.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "link/line_settings.hpp"

namespace LibSerial {
class SerialPort;
}

namespace ncd::comms {

// The device is missing, was unplugged, or failed: the sender reopens with back-off.
class LinkError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class SerialLink {
 public:
  // Opens and configures the device; throws LinkError naming the device and the reason.
  explicit SerialLink(const LineSettings& line);
  ~SerialLink();
  SerialLink(const SerialLink&) = delete;
  SerialLink& operator=(const SerialLink&) = delete;

  // Writes what the kernel takes now; returns the count. Throws LinkError on a hang-up or I/O
  // error.
  std::size_t write_some(std::string_view bytes);
  // Reads what is waiting (up to `capacity`); 0 when nothing is. Throws LinkError on hang-up.
  std::size_t read_some(char* buffer, std::size_t capacity);
  // Waits up to timeout_ms for input (and for room to write when want_write); true if ready.
  // Throws LinkError when the device hangs up.
  bool wait(int timeout_ms, bool want_write);
  // Characters written but not yet sent by the UART (TIOCOUTQ); 0 on a pseudo-terminal, which
  // hands bytes straight to the other side.
  int output_queue() const;
  // The CTS line, or nullopt where the device has no modem lines (a pseudo-terminal).
  std::optional<bool> cts() const;
  const LineSettings& settings() const { return line_; }

 private:
  LineSettings line_;
  std::unique_ptr<LibSerial::SerialPort> port_;
  int fd_ = -1;
};

}  // namespace ncd::comms
