// The one way ncd opens an input file (machine file, service config, path JSON, G-code, teach,
// frame and touch points, a service job's "path"): it must be a regular file. A directory, a
// FIFO, a socket or a device is refused with an InputError before anything is read, and the
// check never blocks: the path is stat()ed first (so a device is never opened: opening a serial
// port would raise its DTR line), then opened with O_NONBLOCK (a FIFO that appeared in between
// cannot block the open) and fstat()ed again on the open descriptor, which is what is read.
// Files above kMaxInputFileBytes are refused. See docs/input-ranges.md, "Input files".
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstring>
#include <string>

#include "core/error.hpp"

namespace ncd {

inline constexpr std::size_t kMaxInputFileBytes = std::size_t{1} << 30;  // 1 GiB

namespace detail {

inline const char* file_kind(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  return "not a regular file";
}

// "PATH (WHAT)" or "PATH" for messages.
inline std::string file_label(const std::string& path, const std::string& what) {
  return what.empty() ? path : path + " (" + what + ")";
}

[[noreturn]] inline void refuse_kind(const std::string& path, const std::string& what,
                                     mode_t mode) {
  throw InputError(file_label(path, what) + " is " + file_kind(mode) +
                   ", not a regular file; give the path of a file");
}

[[noreturn]] inline void refuse_errno(const std::string& path, const std::string& what,
                                      const char* action, int err) {
  throw InputError("cannot " + std::string(action) + " " + file_label(path, what) + ": " +
                   std::strerror(err) + "; check the path and its permissions");
}

}  // namespace detail

// Throws InputError unless path names an existing regular file (symbolic links followed).
// For readers that open the file themselves; read_input_file() also re-checks the descriptor.
inline void require_regular_file(const std::string& path, const std::string& what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) detail::refuse_errno(path, what, "open", errno);
  if (!S_ISREG(st.st_mode)) detail::refuse_kind(path, what, st.st_mode);
}

// The whole of a regular file, or an InputError naming the file and `what` (the flag or the
// key that named it, such as "--machine").
inline std::string read_input_file(const std::string& path, const std::string& what,
                                   std::size_t max_bytes = kMaxInputFileBytes) {
  require_regular_file(path, what);
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) detail::refuse_errno(path, what, "open", errno);
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) detail::refuse_errno(path, what, "read", errno);
  if (!S_ISREG(st.st_mode)) detail::refuse_kind(path, what, st.st_mode);
  const auto too_large = [&] {
    return InputError(detail::file_label(path, what) + " is larger than " +
                      std::to_string(max_bytes) + " bytes; split it or give a smaller file");
  };
  if (static_cast<unsigned long long>(st.st_size) > max_bytes) throw too_large();
  std::string text;
  text.reserve(static_cast<std::size_t>(st.st_size));
  char buffer[65536];
  for (;;) {
    const ssize_t got = ::read(fd, buffer, sizeof buffer);
    if (got < 0) {
      if (errno == EINTR) continue;
      detail::refuse_errno(path, what, "read", errno);
    }
    if (got == 0) break;
    if (text.size() + static_cast<std::size_t>(got) > max_bytes) throw too_large();
    text.append(buffer, static_cast<std::size_t>(got));
  }
  return text;
}

}  // namespace ncd
