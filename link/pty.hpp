// A pseudo-terminal pair that stands in for a serial port: the controller side keeps the master,
// the sender opens the slave through a symbolic link at a fixed path (e.g. /tmp/cnc0 →
// /dev/pts/7), as it would open /dev/ttyS0. The slave is set raw (cfmakeraw), so nothing is
// echoed, translated (CR/LF) or taken as a signal character.
//
// The pair also holds one descriptor of the slave for its whole life. Without it, the master
// reads EIO and polls POLLHUP whenever no sender has the slave open, and what the controller
// wrote (DC1, replies) would be at the mercy of the last close. Who else opens and closes the
// slave is watched with inotify, so the controller can tell a sender that connects or goes away.
//
// What a pty does not carry: there is no baud rate, no framing or parity, no modem lines (RTS,
// CTS, DCD: TIOCMGET fails on a pty) and no output queue (TIOCOUTQ on the slave reads 0 however
// much is waiting). Bytes written to the slave wait in the kernel (some 4 KiB readable at the
// master, about 13 KiB in all before the writer blocks) until the master reads them.
#pragma once

#include <string>
#include <vector>

namespace ncd::comms {

class Pty {
 public:
  // An open or a close of the slave by someone other than this object.
  enum class SlaveEvent { Opened, Closed };

  // Opens a pair and links `link` at its slave (see open()).
  explicit Pty(std::string link);
  // Closes (see close()).
  ~Pty();
  Pty(const Pty&) = delete;
  Pty& operator=(const Pty&) = delete;

  // Opens a new pair (posix_openpt, grantpt, unlockpt), sets the slave raw and points the link
  // at it: an existing symbolic link at the path is replaced atomically (rename), anything else
  // at the path is refused. Throws InputError naming the path and the way out when the link
  // cannot be made, std::system_error when the system has no pty to give. Closes a pair that
  // is still open first.
  void open();
  // Closes both sides (a sender holding the slave sees a hangup) and removes the link if it
  // still points at this pair's slave. Idempotent.
  void close();
  bool is_open() const { return master_ >= 0; }

  // The master side, non-blocking; -1 when closed.
  int master() const { return master_; }
  // The descriptor of the slave this object holds (never read; used for tcflush); -1 when closed.
  int held_slave() const { return slave_; }
  // The inotify descriptor that becomes readable when the slave is opened or closed; -1 when
  // closed.
  int watch_fd() const { return watch_; }
  // The slave's name, e.g. /dev/pts/7; empty when closed.
  const std::string& device() const { return device_; }
  // The path of the symbolic link.
  const std::string& link() const { return link_; }

  // The opens and closes of the slave since the last call, oldest first. Non-blocking.
  std::vector<SlaveEvent> take_slave_events();

 private:
  std::string link_;
  std::string device_;
  int master_ = -1;
  int slave_ = -1;
  int watch_ = -1;
};

// Points `link` at `target`: creates the symbolic link, or replaces an existing one atomically.
// Throws InputError when something other than a symbolic link is at `link`, or when the link
// cannot be created there.
void replace_symlink(const std::string& link, const std::string& target);

}  // namespace ncd::comms
