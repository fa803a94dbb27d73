// The simulated controller's pty and wake pipe; see sim_port.hpp.
#include "sim/sim_port.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <ctime>
#include <system_error>

namespace ncd::comms {

SimPort::SimPort(std::string link) : pty_(std::move(link)) {
  if (::pipe2(wake_.data(), O_NONBLOCK | O_CLOEXEC) != 0) {
    throw std::system_error(errno, std::generic_category(), "pipe2");
  }
}

SimPort::~SimPort() {
  ::close(wake_[0]);
  ::close(wake_[1]);
}

std::size_t SimPort::read(char* to, std::size_t n) {
  if (!pty_.is_open() || n == 0) return 0;
  const ssize_t got = ::read(pty_.master(), to, n);
  return got > 0 ? static_cast<std::size_t>(got) : 0;
}

std::optional<std::size_t> SimPort::write(std::string_view bytes) {
  if (!pty_.is_open()) return std::nullopt;
  const ssize_t n = ::write(pty_.master(), bytes.data(), bytes.size());
  if (n >= 0) return static_cast<std::size_t>(n);
  if (errno == EAGAIN || errno == EINTR) return std::size_t{0};
  return std::nullopt;
}

std::size_t SimPort::waiting() const {
  int n = 0;
  if (!pty_.is_open() || ::ioctl(pty_.master(), FIONREAD, &n) != 0 || n < 0) return 0;
  return static_cast<std::size_t>(n);
}

void SimPort::flush_input() {
  if (pty_.is_open()) ::tcflush(pty_.held_slave(), TCIFLUSH);
}

bool SimPort::wait(double wait_s, bool want_read, bool want_write) {
  std::array<pollfd, 3> fds{};
  fds[0] = {wake_[0], POLLIN, 0};
  nfds_t nfds = 1;
  if (pty_.is_open()) {
    short ev = 0;
    if (want_read) ev |= POLLIN;
    if (want_write) ev |= POLLOUT;
    fds[1] = {pty_.watch_fd(), POLLIN, 0};
    fds[2] = {pty_.master(), ev, 0};
    nfds = 3;
  }
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(wait_s);
  ts.tv_nsec = static_cast<long>((wait_s - static_cast<double>(ts.tv_sec)) * 1e9);
  if (::ppoll(fds.data(), nfds, &ts, nullptr) <= 0) return false;
  if (fds[0].revents & POLLIN) {
    std::array<char, 64> drain{};
    while (::read(wake_[0], drain.data(), drain.size()) > 0) {
    }
  }
  return nfds == 3 && (fds[2].revents & POLLIN) != 0;
}

void SimPort::wake() noexcept {
  const char c = 'w';
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &c, 1);
}

}  // namespace ncd::comms
