// The serve config's [http] table (docs/web-dashboard.md) and the programmed path the page
// draws. The [http] table is read here and taken out of the text before the service's own keys
// go to parse_service_config, which knows nothing of the dashboard.
#include <cmath>
#include <toml.hpp>
#include <variant>

#include "app/toml_text.hpp"
#include "app/web_server.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "toolpath/path_io.hpp"

namespace ncd::app {

namespace {

HttpConfig parse_http(const toml::value& table, const std::string& name) {
  HttpConfig h;
  if (!table.is_table()) {
    throw InputError(name +
                     ": http must be a table, such as [http] listen = \"tcp:127.0.0.1:8080\"");
  }
  for (const auto& [key, v] : table.as_table()) {
    const std::string where = name + ": http." + key;
    const auto text = [&]() -> std::string {
      if (!v.is_string() || v.as_string().str.empty()) {
        throw InputError(where + " = " + toml::format(v) + " must be a non-empty string");
      }
      return v.as_string().str;
    };
    if (key == "listen") {
      const std::string listen = text();
      const comms::ListenAddress address = comms::ListenAddress::parse(listen);
      if (address.kind != comms::ListenAddress::Kind::Tcp) {
        throw InputError(where + " = \"" + listen +
                         "\": the dashboard listens on TCP only; use tcp:127.0.0.1:PORT");
      }
      h.listen = listen;
    } else if (key == "certificate") {
      h.certificate = text();
    } else if (key == "key") {
      h.key = text();
    } else if (key == "assets") {
      h.assets = text();
    } else if (key == "status_hz") {
      const double hz = v.is_floating()  ? v.as_floating()
                        : v.is_integer() ? static_cast<double>(v.as_integer())
                                         : std::nan("");
      if (!(hz >= HttpLimits::kMinStatusHz && hz <= HttpLimits::kMaxStatusHz)) {
        throw InputError(where + " = " + toml::format(v) +
                         " is out of range: status snapshots per second, at least " +
                         nlohmann::json(HttpLimits::kMinStatusHz).dump() + " and at most " +
                         nlohmann::json(HttpLimits::kMaxStatusHz).dump() + " (default 10)");
      }
      h.status_hz = hz;
    } else {
      throw InputError("unknown key " + where +
                       "; [http] takes listen, certificate, key, assets, status_hz");
    }
  }
  if (h.certificate.empty() != h.key.empty()) {
    throw InputError(name +
                     ": [http] has only one of certificate and key; TLS needs both (PEM files), "
                     "plain HTTP neither");
  }
  if ((!h.certificate.empty() || !h.assets.empty()) && !h.listen) {
    throw InputError(name + ": [http] has no listen; add listen = \"tcp:127.0.0.1:PORT\"");
  }
  return h;
}

}  // namespace

ServeConfig parse_serve_config(const std::string& text, const std::string& name) {
  ServeConfig c;
  toml::value root = parse_toml_text(text, name, "service config");
  if (!root.is_table() || !root.contains("http")) {
    c.service = parse_service_config(text, name);
    return c;
  }
  c.http = parse_http(root.at("http"), name);
  root.as_table().erase("http");
  c.service = parse_service_config(toml::format(root), name);
  return c;
}

ServeConfig load_serve_config(const std::string& path) {
  return parse_serve_config(read_input_file(path, "service config, --config"), path);
}

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
