// Serial link: libserial opens and configures the port; the hot calls go to the descriptor.
#include "link/serial_link.hpp"

#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <libserial/SerialPort.h>
#include <cerrno>
#include <cstring>

namespace ncd::comms {
namespace {

LibSerial::BaudRate baud_rate(int baud) {
  using LibSerial::BaudRate;
  switch (baud) {
    case 300:
      return BaudRate::BAUD_300;
    case 600:
      return BaudRate::BAUD_600;
    case 1200:
      return BaudRate::BAUD_1200;
    case 2400:
      return BaudRate::BAUD_2400;
    case 4800:
      return BaudRate::BAUD_4800;
    case 9600:
      return BaudRate::BAUD_9600;
    case 19200:
      return BaudRate::BAUD_19200;
    case 38400:
      return BaudRate::BAUD_38400;
    case 57600:
      return BaudRate::BAUD_57600;
    case 115200:
      return BaudRate::BAUD_115200;
    default:
      throw LinkError("baud " + std::to_string(baud) + " is not a standard rate");
  }
}

std::string errno_text() {
  return std::strerror(errno);
}

}  // namespace

SerialLink::SerialLink(const LineSettings& line)
    : line_(line), port_(std::make_unique<LibSerial::SerialPort>()) {
  using namespace LibSerial;
  try {
    port_->Open(line.device);
    port_->SetBaudRate(baud_rate(line.baud));
    port_->SetCharacterSize(line.data_bits == 7 ? CharacterSize::CHAR_SIZE_7
                                                : CharacterSize::CHAR_SIZE_8);
    port_->SetParity(line.parity == Parity::None   ? LibSerial::Parity::PARITY_NONE
                     : line.parity == Parity::Even ? LibSerial::Parity::PARITY_EVEN
                                                   : LibSerial::Parity::PARITY_ODD);
    port_->SetStopBits(line.stop_bits == 2 ? StopBits::STOP_BITS_2 : StopBits::STOP_BITS_1);
    port_->SetFlowControl(line.flow == Flow::RtsCts ? FlowControl::FLOW_CONTROL_HARDWARE
                                                    : FlowControl::FLOW_CONTROL_NONE);
    port_->SetSerialPortBlockingStatus(false);
    fd_ = port_->GetFileDescriptor();
  } catch (const std::exception& e) {
    throw LinkError("cannot open " + line.device + " at " + describe(line) + ": " + e.what());
  }
}

// libserial's Close() restores the old termios first and throws if the device has gone, leaving
// the port open, and its destructor would then throw again. So a vanished device's descriptor
// is replaced (dup2) by a fresh pseudo-terminal, on which Close() succeeds.
SerialLink::~SerialLink() {
  if (!port_->IsOpen()) return;
  try {
    port_->Close();
    return;
  } catch (const std::exception&) {  // the device vanished: see above
  }
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  int stand_in = -1;
  if (master >= 0 && ::grantpt(master) == 0 && ::unlockpt(master) == 0) {
    stand_in = ::open(::ptsname(master), O_RDWR | O_NOCTTY);
  }
  bool closed = false;
  if (stand_in >= 0 && ::dup2(stand_in, fd_) == fd_) {
    try {
      port_->Close();
      closed = true;
    } catch (const std::exception&) {  // handled below
    }
  }
  if (stand_in >= 0) ::close(stand_in);
  if (master >= 0) ::close(master);
  if (!closed) {
    ::close(fd_);
    (void)port_.release();  // cannot be destroyed safely; a few bytes, once per lost port
  }
}

std::size_t SerialLink::write_some(std::string_view bytes) {
  if (bytes.empty()) return 0;
  const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
  if (n >= 0) return static_cast<std::size_t>(n);
  if (errno == EAGAIN || errno == EINTR) return 0;
  throw LinkError("write to " + line_.device + " failed: " + errno_text());
}

std::size_t SerialLink::read_some(char* buffer, std::size_t capacity) {
  const ssize_t n = ::read(fd_, buffer, capacity);
  if (n > 0) return static_cast<std::size_t>(n);
  if (n < 0 && (errno == EAGAIN || errno == EINTR)) return 0;
  if (n == 0) return 0;  // raw tty with VMIN 0: nothing waiting
  throw LinkError("read from " + line_.device + " failed: " + errno_text());
}

bool SerialLink::wait(int timeout_ms, bool want_write) {
  pollfd p{fd_, static_cast<short>(POLLIN | (want_write ? POLLOUT : 0)), 0};
  const int r = ::poll(&p, 1, timeout_ms);
  if (r < 0) {
    if (errno == EINTR) return false;
    throw LinkError("poll on " + line_.device + " failed: " + errno_text());
  }
  if ((p.revents & (POLLHUP | POLLERR | POLLNVAL)) != 0) {
    throw LinkError(line_.device + " hung up (the device vanished or the far end closed)");
  }
  return r > 0;
}

int SerialLink::output_queue() const {
  int queued = 0;
  if (::ioctl(fd_, TIOCOUTQ, &queued) != 0) return 0;
  return queued;
}

std::optional<bool> SerialLink::cts() const {
  int bits = 0;
  if (::ioctl(fd_, TIOCMGET, &bits) != 0) return std::nullopt;
  return (bits & TIOCM_CTS) != 0;
}

}  // namespace ncd::comms
