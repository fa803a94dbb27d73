// Atomic file output: a reader never sees half a program, and a failed run leaves nothing.
#include "app/output.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>

#include "core/error.hpp"

namespace ncd::app {

void write_output(const std::string& path, const std::string& text) {
  if (path.empty() || path == "-") {
    std::cout << text << std::flush;
    if (!std::cout) throw std::runtime_error("cannot write to standard output");
    return;
  }
  const std::filesystem::path target(path);
  const std::filesystem::path tmp =
      target.parent_path() / ("." + target.filename().string() + ".tmp" + std::to_string(getpid()));
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      throw InputError("cannot create " + tmp.string() + ": " + std::strerror(errno) +
                       "; check that the folder exists and is writable (-o)");
    }
    out << text;
    out.flush();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + tmp.string());
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, target, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error("cannot write " + path + ": " + ec.message());
  }
}

StreamedFile::StreamedFile(const std::string& path, const std::string& what, int buffer_bytes)
    : path_(path) {
  const std::filesystem::path target(path_);
  tmp_ = (target.parent_path() / ("." + target.filename().string() + ".tmp")).string();
  file_ = std::fopen(tmp_.c_str(), "wb");
  if (!file_) {
    throw InputError("cannot create " + tmp_ + "; check that the folder of " + what + " exists");
  }
  std::setvbuf(file_, nullptr, _IOFBF, static_cast<std::size_t>(buffer_bytes));
}

StreamedFile::~StreamedFile() {
  if (file_) {
    std::fclose(file_);
    std::remove(tmp_.c_str());
  }
}

void StreamedFile::commit() {
  const bool ok = std::fflush(file_) == 0 && std::ferror(file_) == 0;
  std::fclose(file_);
  file_ = nullptr;
  if (!ok || std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    std::remove(tmp_.c_str());
    throw std::runtime_error("cannot write " + path_);
  }
}

}  // namespace ncd::app
