// Writing results: to stdout, or to a file that appears whole or not at all.
#pragma once

#include <cstddef>
#include <cstdio>
#include <string>

namespace ncd::app {

// Writes text to path atomically (temporary file in the same folder, then rename), or to
// stdout when path is empty or "-". Throws std::runtime_error naming the path on failure.
void write_output(const std::string& path, const std::string& text);

// A file written as a run goes (setpoints, blocks): into a temporary file beside it, renamed
// by commit(); destroyed without commit(), it leaves nothing behind.
class StreamedFile {
 public:
  // Throws InputError naming the temporary file and the flag (`what`) if it cannot be created.
  StreamedFile(const std::string& path, const std::string& what, int buffer_bytes);
  ~StreamedFile();
  StreamedFile(const StreamedFile&) = delete;
  StreamedFile& operator=(const StreamedFile&) = delete;
  void write(const char* bytes, std::size_t size) { std::fwrite(bytes, 1, size, file_); }
  void commit();  // flush and rename; throws std::runtime_error on failure

 private:
  std::string path_, tmp_;
  std::FILE* file_ = nullptr;
};

}  // namespace ncd::app
