// The [http] table of the serve config (docs/web-dashboard.md): where the dashboard listens,
// its TLS files, its assets and its status rate. Read by the service config's one parser
// (api/service_config.hpp); the server is api/web_server.hpp.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <toml.hpp>

namespace ncd::api {

// No table, or no listen: no web server.
struct HttpConfig {
  std::optional<std::string> listen;  // "tcp:HOST:PORT"; loopback unless a token is set
  std::string certificate, key;       // PEM files: TLS (https, wss) when both are given
  std::string assets;                 // a directory with index.html, app.js, style.css
  double status_hz = 10.0;            // status snapshots per second to each page
};

// Limits of the [http] keys and of the page's messages (docs/web-dashboard.md).
struct HttpLimits {
  static constexpr double kMinStatusHz = 1.0;
  static constexpr double kMaxStatusHz = 50.0;
  static constexpr std::size_t kMaxMessageBytes = std::size_t{8} << 20;  // a WebSocket message
  static constexpr std::size_t kMaxUploadNameBytes = 128;
  static constexpr std::size_t kMaxPreviewPoints = 20000;  // of the programmed path sent
  static constexpr std::size_t kRecentEvents = 64;         // the service's events kept for pages
};

// Reads the [http] table; `where` names it in messages ("serve.toml: http"). Throws InputError
// naming the key, the value, the limit and a way out.
HttpConfig parse_http_config(const toml::value& table, const std::string& where);

}  // namespace ncd::api
