// The service's control socket: newline-delimited JSON over loopback TCP or a Unix socket, one
// request and one reply per line, plus status streaming ("subscribe"). This is the transport and
// protocol layer only; what the commands do is a ControlHandler's business. Everything runs on
// the io_context given (the service's I/O thread); the server starts no threads.
#pragma once

#include "core/input_ranges.hpp"

#include <boost/asio/io_context.hpp>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

namespace ncd::comms {

// Where the server listens: "tcp:HOST:PORT" or "unix:PATH".
struct ListenAddress {
  enum class Kind { Tcp, Unix };
  Kind kind = Kind::Tcp;
  std::string host;  // "127.0.0.1", "::1" (no brackets), "localhost"; empty for Unix
  std::uint16_t port = 0;
  std::string path;  // Unix only

  // Parses tcp:IPV4:PORT, tcp:[IPV6]:PORT, tcp:localhost:PORT or unix:PATH; throws InputError.
  static ListenAddress parse(const std::string& text);
  // True for Unix sockets, "localhost" and loopback addresses (127/8, ::1, ::ffff:127/104).
  bool is_loopback() const;
  // The form parse() reads back.
  std::string to_string() const;
};

// The service logic behind the socket. Both calls run on the I/O thread and must not block.
class ControlHandler {
 public:
  virtual ~ControlHandler() = default;
  // Gets an object with a string "cmd" (and the right token when one is configured); returns
  // the reply object. May throw InputError (reply "error": what) or std::exception (reply
  // "error": "internal error: what"). "ok": true is added when the reply leaves it out.
  virtual nlohmann::json handle(const nlohmann::json& request) = 0;
  // One status snapshot, sent as a line to each subscriber at its rate.
  virtual nlohmann::json status() = 0;
  // The submitted job's programmed path and listing for the dashboard (api::program_view); the
  // same object until the next submit; null when there is none.
  virtual std::shared_ptr<const nlohmann::json> program_view() { return nullptr; }
};

struct ServerOptions {
  std::size_t max_line_bytes = 65536;  // longer request lines get an error reply and are skipped
  std::optional<std::string> token;    // required in every request ("token") when set
  double min_subscribe_hz = ranges::kMinSubscribeHz;  // lower bound of "hz" in subscribe
  double max_subscribe_hz = 1000;                     // upper bound of "hz" in subscribe
};

// The checks of one request line (without its newline), in the order described in
// control_server.cpp: valid JSON (at most 64 levels deep), an object, the token, a string
// "cmd", and for "subscribe" its "hz". Never throws for any input.
struct RequestCheck {
  bool to_handler = false;             // the request passed; the handler answers it
  nlohmann::json request;              // the parsed request when to_handler
  nlohmann::json reply;                // the reply when !to_handler (an error or subscribe's ok)
  std::optional<double> subscribe_hz;  // a valid subscribe's rate
};
RequestCheck check_request(std::string_view line, const ServerOptions& options);

// {"ok": false, "error": message}.
nlohmann::json error_reply(std::string message);
// The reply of one request that passed check_request, as the socket, the web dashboard and MQTT
// all send it: call(request), made well formed. An InputError becomes {"ok":false,"error":what},
// any other exception "internal error: what"; a reply that is not an object, or whose "ok" is
// not a boolean, is an internal error; "ok": true is added when left out, and a false "ok"
// without "error" gets one.
nlohmann::json handler_reply(const std::function<nlohmann::json(const nlohmann::json&)>& call,
                             const nlohmann::json& request);

class ControlServer {
 public:
  // Binds and listens at once; throws InputError for a non-loopback TCP address without a
  // token, a live Unix socket at the path, or an address that cannot be bound.
  ControlServer(boost::asio::io_context& io, const ListenAddress& address, ControlHandler& handler,
                const ServerOptions& options = {});
  // Closes (see close()).
  ~ControlServer();
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  // The bound TCP port (the kernel's choice for port 0); 0 for a Unix socket.
  std::uint16_t port() const { return port_; }
  // Stops accepting, closes every connection, removes the Unix socket file. Idempotent. Call it
  // on the I/O thread or while the io_context is not running.
  void close();
  // Open client connections; safe to read from any thread.
  std::size_t connections() const;

  struct State;

 private:
  std::shared_ptr<State> state_;
  std::uint16_t port_ = 0;
};

}  // namespace ncd::comms
