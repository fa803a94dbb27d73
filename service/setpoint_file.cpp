// Setpoints CSV: numbers by std::to_chars with fixed decimals (nm positions, 1e-4 mm/min feed),
// so the same run gives the same bytes.
#include "service/setpoint_file.hpp"

#include <charconv>
#include <filesystem>
#include <stdexcept>

#include "core/error.hpp"

namespace ncd::service {

SetpointFileSink::SetpointFileSink(const std::string& path, char rotary_axis) {
  if (path.empty()) return;
  file_ = std::make_unique<StreamedFile>(path, "--setpoints", 1 << 20);
  rotary_ = rotary_axis != 0;
  std::string header = "t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit";
  if (rotary_) header += std::string(",") + rotary_axis + "_deg";
  header += '\n';
  file_->write(header.data(), header.size());
}

void SetpointFileSink::write(const motion::Setpoint& sp) {
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
  if (rotary_) {
    *p++ = ',';
    p = std::to_chars(p, end, sp.rotary_deg == 0.0 ? 0.0 : sp.rotary_deg, std::chars_format::fixed,
                      6)
            .ptr;
  }
  *p++ = '\n';
  file_->write(line, static_cast<std::size_t>(p - line));
}

void SetpointFileSink::commit() {
  if (file_) file_->commit();
}

}  // namespace ncd::service
