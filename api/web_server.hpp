// The web dashboard of `ncd serve` (docs/web-dashboard.md): an HTTP server (Boost.Beast) on the
// service's own io_context that serves the page (index.html, app.js, style.css, embedded in the
// binary or read from a directory) and a WebSocket at /ws. Over the WebSocket the page sends
// the socket protocol's requests, which take the same checks (comms::check_request: the token)
// and the same comms::ControlHandler as the control socket; it receives status snapshots at a
// set rate. Nothing here runs on the cycle thread.
#pragma once

#include <boost/asio/io_context.hpp>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "api/control_server.hpp"
#include "api/http_config.hpp"
#include "api/intake.hpp"
#include "gcode/ngc/interpreter.hpp"

namespace ncd::api {

// The programmed path of a path file as a polyline for the page: {"points": [[x,y,z], ...]},
// NURBS sampled, at most HttpLimits::kMaxPreviewPoints points. Throws InputError.
nlohmann::json path_preview(const std::string& file, const toolpath::InterpretOptions& ngc);

class WebServer {
 public:
  // Binds and listens at once. Throws InputError for an address that is not tcp:, a
  // non-loopback address without a token, unreadable TLS files, a port that cannot be bound.
  WebServer(boost::asio::io_context& io, const HttpConfig& config, comms::ControlHandler& handler,
            const std::optional<std::string>& token, const toolpath::InterpretOptions& ngc);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  std::uint16_t port() const { return port_; }
  // "http://127.0.0.1:PORT/" (https with TLS).
  std::string url() const;
  // One of the service's events (api/event_feed.hpp), on the io_context's thread: each open
  // page gets it as {"event": …} at its next status tick; the last kRecentEvents are kept for
  // pages that open later.
  void push_event(const nlohmann::json& event);
  // Stops accepting; open pages are closed at their next status tick. Idempotent.
  void close();

  struct State;

 private:
  std::shared_ptr<State> state_;
  std::uint16_t port_ = 0;
};

}  // namespace ncd::api
