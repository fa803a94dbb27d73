// Setpoints CSV: numbers by std::to_chars with fixed decimals (nm positions, 1e-4 mm/min feed),
// so the same run gives the same bytes.
#include "app/setpoint_sink.hpp"

#include <charconv>
#include <filesystem>
#include <stdexcept>

#include "core/error.hpp"

namespace ncd::app {

SetpointSink::SetpointSink(const std::string& path) : path_(path) {
  if (path_.empty()) return;
  const std::filesystem::path target(path_);
  tmp_ = (target.parent_path() / ("." + target.filename().string() + ".tmp")).string();
  file_ = std::fopen(tmp_.c_str(), "wb");
  if (!file_) {
    throw InputError("cannot create " + tmp_ +
                     "; check that the folder of the setpoints file exists");
  }
  std::setvbuf(file_, nullptr, _IOFBF, 1 << 20);
  std::fputs("t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit\n", file_);
}

SetpointSink::~SetpointSink() {
  if (file_) {
    std::fclose(file_);
    std::remove(tmp_.c_str());
  }
}

void SetpointSink::write(const motion::Setpoint& sp) {
  if (!file_) return;
  char line[160];
  char* p = line;
  char* end = line + sizeof line;
  const auto put = [&](double v, int decimals) {
    p = std::to_chars(p, end, v == 0.0 ? 0.0 : v, std::chars_format::fixed, decimals).ptr;
    *p++ = ',';
  };
  put(sp.t_s, 6);
  put(sp.p.x(), 6);
  put(sp.p.y(), 6);
  put(sp.p.z(), 6);
  put(sp.v_mm_per_s * 60.0, 4);
  const char* name = motion::limit_name(sp.limit_id);
  while (*name) *p++ = *name++;
  *p++ = '\n';
  std::fwrite(line, 1, static_cast<std::size_t>(p - line), file_);
}

void SetpointSink::commit() {
  if (!file_) return;
  const bool ok = std::fflush(file_) == 0 && std::ferror(file_) == 0;
  std::fclose(file_);
  file_ = nullptr;
  if (!ok || std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    std::remove(tmp_.c_str());
    throw std::runtime_error("cannot write " + path_);
  }
}

}  // namespace ncd::app
