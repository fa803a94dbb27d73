// The programmed path the dashboard's page draws (docs/web-dashboard.md).
#include <variant>

#include "api/web_server.hpp"
#include "core/error.hpp"
#include "gcode/path_io.hpp"

namespace ncd::app {

nlohmann::json path_preview(const std::string& file, const toolpath::InterpretOptions& ngc) {
  const toolpath::Path path = toolpath::read_path_file(file, ngc);
  constexpr int kSamplesPerCurve = 64;
  std::size_t total = 0;
  for (const auto& seg : path.segments) {
    if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      total += line->points.size();
    } else {
      total += kSamplesPerCurve + 1;
    }
  }
  // Every step-th point (and each segment's last), so that the preview stays bounded.
  const std::size_t step = std::max<std::size_t>(
      1, (total + HttpLimits::kMaxPreviewPoints - 1) / HttpLimits::kMaxPreviewPoints);
  nlohmann::json points = nlohmann::json::array();
  nlohmann::json rapid = nlohmann::json::array();
  std::size_t n = 0;
  const auto add = [&](const Vec3& p, bool last, bool is_rapid) {
    if (n++ % step == 0 || last) {
      points.push_back({p.x(), p.y(), p.z()});
      rapid.push_back(is_rapid);
    }
  };
  for (const auto& seg : path.segments) {
    if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      for (std::size_t i = 0; i < line->points.size(); ++i) {
        add(line->points[i], i + 1 == line->points.size(), seg.rapid);
      }
    } else {
      const auto& curve = std::get<toolpath::NurbsCurve>(seg.geometry);
      const double u0 = curve.u_begin(), u1 = curve.u_end();
      for (int i = 0; i <= kSamplesPerCurve; ++i) {
        const double u = u0 + (u1 - u0) * i / kSamplesPerCurve;
        add(curve.eval(u).p, i == kSamplesPerCurve, seg.rapid);
      }
    }
  }
  double feed_max = 0.0;
  for (const auto& seg : path.segments) {
    if (seg.feed_mm_per_min) feed_max = std::max(feed_max, *seg.feed_mm_per_min);
  }
  return {{"points", points},
          {"rapid", rapid},
          {"segments", path.segments.size()},
          {"programmed_feed_max_mm_per_min", feed_max}};
}

}  // namespace ncd::app
