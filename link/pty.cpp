// Pseudo-terminal pair linked at a fixed path; see pty.hpp.
#include "link/pty.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "core/error.hpp"

namespace ncd::comms {
namespace {

// Throws std::system_error for the failed call `what`.
[[noreturn]] void fail(const std::string& what) {
  throw std::system_error(errno, std::generic_category(), what);
}

// The target of the symbolic link at path, or "" when there is none.
std::string read_link(const std::string& path) {
  std::array<char, 4096> buf{};
  const ssize_t n = ::readlink(path.c_str(), buf.data(), buf.size() - 1);
  return n > 0 ? std::string(buf.data(), static_cast<std::size_t>(n)) : std::string();
}

}  // namespace

void replace_symlink(const std::string& link, const std::string& target) {
  if (link.empty()) throw InputError("the link path is empty: give --link PATH, e.g. /tmp/cnc0");
  struct stat st {};
  if (::lstat(link.c_str(), &st) == 0 && !S_ISLNK(st.st_mode)) {
    throw InputError("cannot link the pseudo-terminal at " + link +
                     ": something other than a symbolic link is there; remove it or choose "
                     "another --link path");
  }
  const std::string tmp = link + ".tmp" + std::to_string(::getpid());
  ::unlink(tmp.c_str());
  if (::symlink(target.c_str(), tmp.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    throw InputError("cannot create the link " + link + " (" + why + "): check that the folder " +
                     std::filesystem::path(link).parent_path().string() +
                     " exists and is writable, or choose another --link path");
  }
  if (::rename(tmp.c_str(), link.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    ::unlink(tmp.c_str());
    throw InputError("cannot put the link at " + link + " (" + why +
                     "): remove what is there or choose another --link path");
  }
}

Pty::Pty(std::string link) : link_(std::move(link)) {
  open();
}

Pty::~Pty() {
  close();
}

void Pty::open() {
  close();
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (master < 0) fail("posix_openpt");
  std::array<char, 128> name{};
  if (::grantpt(master) != 0 || ::unlockpt(master) != 0 ||
      ::ptsname_r(master, name.data(), name.size()) != 0) {
    const int e = errno;
    ::close(master);
    errno = e;
    fail("grantpt/unlockpt/ptsname_r");
  }
  const int slave = ::open(name.data(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (slave < 0) {
    const int e = errno;
    ::close(master);
    errno = e;
    fail(std::string("open ") + name.data());
  }
  termios tio{};
  if (::tcgetattr(slave, &tio) == 0) {
    ::cfmakeraw(&tio);
    ::tcsetattr(slave, TCSANOW, &tio);
  }
  // Watched after our own open, so only other openers are reported.
  const int watch = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  if (watch < 0 || ::inotify_add_watch(watch, name.data(), IN_OPEN | IN_CLOSE) < 0) {
    const int e = errno;
    if (watch >= 0) ::close(watch);
    ::close(slave);
    ::close(master);
    errno = e;
    fail(std::string("inotify on ") + name.data());
  }
  master_ = master;
  slave_ = slave;
  watch_ = watch;
  device_ = name.data();
  try {
    replace_symlink(link_, device_);
  } catch (...) {
    close();
    throw;
  }
}

void Pty::close() {
  if (master_ < 0) return;
  if (read_link(link_) == device_) ::unlink(link_.c_str());  // gone before the hang-up is seen
  ::close(watch_);  // before our own close of the slave, which is not to be reported
  ::close(slave_);
  ::close(master_);
  master_ = slave_ = watch_ = -1;
  device_.clear();
}

std::vector<Pty::SlaveEvent> Pty::take_slave_events() {
  std::vector<SlaveEvent> events;
  if (watch_ < 0) return events;
  alignas(inotify_event) std::array<char, 4096> buf{};
  for (;;) {
    const ssize_t n = ::read(watch_, buf.data(), buf.size());
    if (n <= 0) break;
    for (std::size_t off = 0; off < static_cast<std::size_t>(n);) {
      inotify_event ev{};
      std::memcpy(&ev, buf.data() + off, sizeof ev);
      if (ev.mask & IN_OPEN) events.push_back(SlaveEvent::Opened);
      if (ev.mask & (IN_CLOSE_WRITE | IN_CLOSE_NOWRITE)) events.push_back(SlaveEvent::Closed);
      off += sizeof ev + ev.len;
    }
  }
  return events;
}

}  // namespace ncd::comms
