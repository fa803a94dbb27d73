// The programmed path and the listing the dashboard's page draws (docs/web-dashboard.md, "The
// preview" and "The listing"): the job's path as polylines (NURBS sampled at 65 points each, at
// most HttpLimits::kMaxPreviewPoints points, every k-th kept and each segment's last), and the
// text of an NC program, line by line, bounded.
#include <fstream>
#include <sstream>
#include <variant>

#include "api/intake.hpp"
#include "api/web_server.hpp"
#include "core/error.hpp"
#include "gcode/path_io.hpp"

namespace ncd::api {

nlohmann::json path_preview(const std::string& file, const toolpath::InterpretOptions& ngc) {
  return path_preview(toolpath::read_path_file(file, ngc));
}

nlohmann::json path_preview(const toolpath::Path& path) {
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

namespace {

// The listing of a program read from `in` (the file `file`, or a program made in memory).
nlohmann::json listed_view(nlohmann::json view, std::istream& in, const std::string& file) {
  nlohmann::json lines = nlohmann::json::array();
  std::size_t bytes = 0;
  bool truncated = false;
  for (std::string line; std::getline(in, line);) {
    if (lines.empty() && line.find_first_not_of(" \t\r") != std::string::npos &&
        line[line.find_first_not_of(" \t\r")] == '{') {
      return view;  // a JSON path: no program text to list
    }
    if (lines.size() >= kMaxListingLines || bytes + line.size() > kMaxListingBytes) {
      truncated = true;
      break;
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    bytes += line.size();
    // Bytes that are not UTF-8 would make the JSON unwritable: shown as '?'.
    for (char& c : line) {
      if (static_cast<unsigned char>(c) >= 0x80) c = '?';
    }
    lines.push_back(std::move(line));
  }
  view["listing"] = std::move(lines);
  view["listing_file"] = file;
  if (truncated) view["listing_truncated"] = true;
  return view;
}

}  // namespace

nlohmann::json program_view(const std::string& job, const toolpath::Path& path,
                            const std::string& file, const std::string& text) {
  nlohmann::json view = path_preview(path);
  view["job"] = job;
  view["listing"] = nullptr;
  if (!text.empty()) {
    std::istringstream in(text);
    return listed_view(std::move(view), in, file);
  }
  if (file.empty()) return view;
  std::ifstream in(file, std::ios::binary);
  return listed_view(std::move(view), in, file);
}

}  // namespace ncd::api
