// The one output writer of ncd (rule in output.hpp, reasons in docs/hardening.md).
//
// Signal cleanup: a temporary file's name is kept in a fixed table of slots (no allocation in
// the handler). The SIGINT/SIGTERM handler, installed only where the signal still has its
// default action (so `ncd serve`, which handles both itself, keeps its own), unlinks every
// temporary in use and re-raises the signal with the default action (SA_RESETHAND), so the
// process ends by the signal as it would have without ncd's handler: a non-zero status.
#include "core/output_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "core/error.hpp"

namespace ncd {
namespace {

namespace fs = std::filesystem;

constexpr int kSlots = 16;                // temporaries open at once (a run has at most 4)
constexpr std::size_t kSlotBytes = 4096;  // PATH_MAX
constexpr int kMaxLinkHops = 40;          // as the kernel's ELOOP limit

struct Slot {
  std::atomic<bool> used{false};
  char path[kSlotBytes] = {};
};
std::array<Slot, kSlots> g_slots;
std::atomic<bool> g_handler_installed{false};

extern "C" void remove_temporaries(int sig) {
  for (Slot& s : g_slots) {
    if (s.used.load(std::memory_order_acquire)) ::unlink(s.path);
  }
  // SA_RESETHAND has restored the default action; the signal is blocked until we return.
  ::raise(sig);
}

void install_handler() {
  if (g_handler_installed.exchange(true)) return;
  for (const int sig : {SIGINT, SIGTERM}) {
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler != SIG_DFL) continue;
    struct sigaction sa {};
    sa.sa_handler = remove_temporaries;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = static_cast<int>(SA_RESETHAND);
    ::sigaction(sig, &sa, nullptr);
  }
}

// Takes a slot for path; -1 when the table is full or the path too long (then a signal may
// leave that one temporary behind, which is reported nowhere but harms nothing).
int take_slot(const std::string& path) {
  install_handler();
  if (path.size() >= kSlotBytes) return -1;
  for (int i = 0; i < kSlots; ++i) {
    Slot& s = g_slots[static_cast<std::size_t>(i)];
    if (s.used.load(std::memory_order_acquire)) continue;
    std::memcpy(s.path, path.c_str(), path.size() + 1);
    s.used.store(true, std::memory_order_release);
    return i;
  }
  return -1;
}

void release_slot(int slot) {
  if (slot >= 0)
    g_slots[static_cast<std::size_t>(slot)].used.store(false, std::memory_order_release);
}

std::string error_text(int err) {
  return std::strerror(err);
}

// The final target of path: symbolic links followed (relative ones from their own folder).
fs::path resolve_links(const fs::path& path, const std::string& what) {
  fs::path p = path;
  for (int hop = 0; hop < kMaxLinkHops; ++hop) {
    struct stat st {};
    if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p;
    std::error_code ec;
    const fs::path next = fs::read_symlink(p, ec);
    if (ec) {
      throw InputError("cannot read the symbolic link " + p.string() + " (" + what +
                       "): " + ec.message());
    }
    p = next.is_absolute() ? next : p.parent_path() / next;
  }
  throw InputError(path.string() + " (" + what + ") is a chain of more than " +
                   std::to_string(kMaxLinkHops) + " symbolic links; give the file itself");
}

[[noreturn]] void refuse_directory(const std::string& path, const std::string& what) {
  throw InputError(path + " (" + what + ") is a directory; give a file name, such as " +
                   (fs::path(path) / "out").string());
}

}  // namespace

void check_output(const std::string& path, const std::string& what) {
  if (path.empty() || path == "-") return;
  const fs::path target = resolve_links(fs::path(path), what);
  struct stat st {};
  if (::stat(target.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) refuse_directory(path, what);
    if (S_ISREG(st.st_mode) || S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode) ||
        S_ISSOCK(st.st_mode)) {
      return;
    }
    throw InputError(path + " (" + what +
                     ") is neither a regular file nor a device, FIFO or socket; give a file name");
  }
  const fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  if (::stat(folder.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    throw InputError("cannot create " + path + " (" + what + "): the folder " + folder.string() +
                     " does not exist; create it or choose another file");
  }
  if (::access(folder.c_str(), W_OK) != 0) {
    throw InputError("cannot create " + path + " (" + what + "): the folder " + folder.string() +
                     " is not writable (" + error_text(errno) + ")");
  }
}

StreamedFile::StreamedFile(const std::string& path, const std::string& what, int buffer_bytes)
    : path_(path), what_(what) {
  if (path.empty() || path == "-") {
    stdout_ = through_ = true;
    file_ = stdout;
    return;
  }
  const fs::path target = resolve_links(fs::path(path), what);
  target_ = target.string();
  struct stat st {};
  const bool exists = ::stat(target_.c_str(), &st) == 0;
  if (exists && S_ISDIR(st.st_mode)) refuse_directory(path, what);
  if (exists && (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode) || S_ISSOCK(st.st_mode))) {
    // Written through: a FIFO blocks here until its reader opens it, as a shell's `>` would.
    const int fd = ::open(target_.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
      throw InputError("cannot open " + path + " (" + what + "): " + error_text(errno));
    }
    file_ = ::fdopen(fd, "wb");
    if (!file_) {
      ::close(fd);
      throw InputError("cannot open " + path + " (" + what + "): " + error_text(errno));
    }
    through_ = true;
  } else if (exists && !S_ISREG(st.st_mode)) {
    throw InputError(path + " (" + what +
                     ") is neither a regular file nor a device, FIFO or socket; give a file name");
  } else {
    const fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    std::string tmpl = (folder / ("." + target.filename().string() + ".tmp.XXXXXX")).string();
    const int fd = ::mkostemp(tmpl.data(), O_CLOEXEC);
    if (fd < 0) {
      throw InputError("cannot create a file in " + folder.string() + " for " + path + " (" + what +
                       "): " + error_text(errno) +
                       "; check that the folder exists and is writable");
    }
    tmp_ = tmpl;
    slot_ = take_slot(tmp_);
    // The permissions a plain create would give (0666 less the umask), or the replaced file's.
    mode_t mode = 0;
    if (exists) {
      mode = st.st_mode & 07777;
    } else {
      const mode_t mask = ::umask(0);
      ::umask(mask);
      mode = 0666 & ~mask;
    }
    ::fchmod(fd, mode);
    file_ = ::fdopen(fd, "wb");
    if (!file_) {
      const int err = errno;
      ::close(fd);
      discard();
      throw InputError("cannot open " + tmp_ + " (" + what + "): " + error_text(err));
    }
  }
  if (buffer_bytes > 0) {
    std::setvbuf(file_, nullptr, _IOFBF, static_cast<std::size_t>(buffer_bytes));
  }
}

void StreamedFile::discard() noexcept {
  if (file_ && !stdout_) std::fclose(file_);
  file_ = nullptr;
  if (!tmp_.empty()) ::unlink(tmp_.c_str());
  release_slot(slot_);
  slot_ = -1;
}

StreamedFile::~StreamedFile() {
  if (stdout_) {
    std::fflush(stdout);
    return;
  }
  discard();
}

void StreamedFile::commit() {
  if (!file_) throw IoError("cannot write " + path_ + " (" + what_ + "): already closed");
  errno = 0;
  const bool flushed = std::fflush(file_) == 0 && std::ferror(file_) == 0 && write_errno_ == 0;
  const int flush_err = write_errno_ != 0 ? write_errno_ : errno;
  if (stdout_) {
    file_ = nullptr;
    if (!flushed) {
      std::clearerr(stdout);
      throw IoError("cannot write to standard output: " +
                    error_text(flush_err != 0 ? flush_err : EIO));
    }
    return;
  }
  int err = flushed ? 0 : (flush_err != 0 ? flush_err : EIO);
  const bool closed = std::fclose(file_) == 0;
  file_ = nullptr;
  if (err == 0 && !closed) err = errno != 0 ? errno : EIO;
  if (err == 0 && !through_ && ::rename(tmp_.c_str(), target_.c_str()) != 0) err = errno;
  if (err != 0) {
    discard();
    throw IoError("cannot write " + path_ + " (" + what_ + "): " + error_text(err));
  }
  release_slot(slot_);
  slot_ = -1;
  tmp_.clear();
}

void write_output(const std::string& path, const std::string& text, const std::string& what) {
  StreamedFile file(path, what, 1 << 16);
  file.write(text.data(), text.size());
  file.commit();
}

}  // namespace ncd
