// Writing results, by one rule for every output flag (see docs/hardening.md, "Output files"):
//   - "-" or empty: standard output, written through;
//   - an existing character device, FIFO or socket: opened and written through (never replaced);
//   - a symbolic link: followed to its final target, which is then treated as below (the link
//     stays a link and now shows the new content);
//   - a directory: refused (InputError, exit 2);
//   - a regular file, or nothing yet: written into a temporary file in the same folder, then
//     renamed over it, so a reader never sees half a file and a failed run leaves nothing. An
//     existing file keeps its permission bits. SIGINT or SIGTERM during the write removes the
//     temporary (async-signal-safe) and the process ends by that signal.
// Errors: a file that cannot be created or opened is an InputError (exit 2) naming it and the
// flag; a failed write or flush (a full disk, /dev/full) is an IoError (exit 1).
#pragma once

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <string>

namespace ncd {

// Writes text to path by the rule above; `what` names the flag in messages ("-o").
void write_output(const std::string& path, const std::string& text, const std::string& what = "-o");

// Checks, before a run, that path could be written by the rule above (not a directory, its
// folder exists and is writable); throws InputError naming the path and the flag. Nothing is
// created.
void check_output(const std::string& path, const std::string& what);

// A file written as a run goes (setpoints, blocks), by the rule above; destroyed without
// commit(), it leaves nothing behind (a written-through device or FIFO keeps what it got).
class StreamedFile {
 public:
  // Throws InputError naming the file and the flag (`what`) if it cannot be opened.
  StreamedFile(const std::string& path, const std::string& what, int buffer_bytes);
  ~StreamedFile();
  StreamedFile(const StreamedFile&) = delete;
  StreamedFile& operator=(const StreamedFile&) = delete;
  void write(const char* bytes, std::size_t size) {
    if (std::fwrite(bytes, 1, size, file_) != size && write_errno_ == 0) write_errno_ = errno;
  }
  void commit();  // flush and rename (or flush only, written through); throws IoError

 private:
  void discard() noexcept;

  std::string path_;    // as given, for messages
  std::string target_;  // the file renamed over (a symbolic link's final target)
  std::string tmp_;     // empty when written through
  std::string what_;
  std::FILE* file_ = nullptr;
  bool through_ = false;  // written through: a device, a FIFO, a socket, standard output
  bool stdout_ = false;
  int slot_ = -1;        // the signal cleanup slot of tmp_
  int write_errno_ = 0;  // the first failed write's errno
};

}  // namespace ncd
