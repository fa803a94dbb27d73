// The control socket: newline-delimited JSON, one request and one reply per line.
//
//   client                                   server (on the I/O thread's io_context)
//   {"cmd":"status"}\n                 ──►   parse, check, ControlHandler::handle()
//                                      ◄──   {"ok":true,...}\n
//   {"cmd":"subscribe","hz":50}\n      ──►   (handled here, not by the handler)
//                                      ◄──   {"ok":true}\n
//                                      ◄──   status()\n  now, then every 1/hz s (steady_timer)
//   {"cmd":"hold"}\n                   ──►   the stream stops; the line is a new request
//                                      ◄──   {"ok":true,...}\n
//
// Every reply carries "ok"; a false one carries "error", a message that says what was wrong and
// what to send instead. A request is checked in this order, and the first failure is the reply:
// valid JSON, an object, the "token" (when one is configured), a string "cmd". "subscribe" needs
// "hz" in [min_subscribe_hz, max_subscribe_hz] (0.1 to 1000 by default); everything else (including
// unknown commands) goes to the handler. None of these errors closes the connection. A line longer
// than max_line_bytes gets one error reply as soon as it is known to be too long; the rest of it,
// up to its newline, is discarded. "\r\n" is accepted. A blank line is no request and gets no
// reply, but like any line it ends a status stream. An unterminated last line before the client's
// end of stream is still answered, and the replies are flushed before the connection closes.
//
// Each connection reads and writes on its own: replies and status lines go to a per-connection
// queue written one async_write at a time. When a client stops reading, its queue grows to
// kMaxQueuedBytes; past that the server stops reading its requests (back-pressure) and skips its
// status snapshots (a later snapshot supersedes them) until the queue drains. A client that
// disconnects or errs closes only its own connection; the job and the other clients go on.
#include "api/control_server.hpp"

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <boost/asio/basic_socket_acceptor.hpp>
#include <boost/asio/generic/stream_protocol.hpp>
#include <boost/asio/ip/address.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/local/stream_protocol.hpp>
#include <boost/asio/socket_base.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/write.hpp>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstring>
#include <deque>
#include <string_view>
#include <unordered_set>

#include "core/error.hpp"
#include "core/input_ranges.hpp"
#include "core/json_input.hpp"

namespace ncd::comms {

namespace asio = boost::asio;
using SocketProtocol = asio::generic::stream_protocol;  // one socket type for TCP and Unix
using boost::system::error_code;
using Clock = std::chrono::steady_clock;
using Json = nlohmann::json;

namespace {

constexpr std::size_t kReadChunkBytes = 4096;
constexpr std::size_t kMaxQueuedBytes = std::size_t{1} << 20;  // per connection, see the top
constexpr std::size_t kMaxDetailBytes = 160;  // of a parser message quoted in an error reply
constexpr auto kAcceptRetry = std::chrono::milliseconds(100);  // after EMFILE and the like
constexpr auto kMinStatusPeriod = std::chrono::microseconds(1);
constexpr const char* kAcceptedForms =
    "tcp:127.0.0.1:PORT, tcp:[::1]:PORT, tcp:localhost:PORT or unix:PATH";

class Connection;

// Throws the InputError for a listen address that cannot be parsed.
[[noreturn]] void bad_address(const std::string& text, const std::string& why) {
  throw InputError("listen address '" + text + "' is invalid: " + why + "; use " + kAcceptedForms);
}

// One protocol line; invalid UTF-8 (a handler's or a parser's quote of the input) is replaced.
std::string to_line(const Json& value) {
  return value.dump(-1, ' ', false, Json::error_handler_t::replace) + "\n";
}

// A number as JSON writes it (5000.0, 0.5), for messages.
std::string number_text(double value) {
  return Json(value).dump();
}

// Cuts a quoted message to kMaxDetailBytes.
std::string clip(std::string text) {
  if (text.size() > kMaxDetailBytes) {
    text.resize(kMaxDetailBytes);
    text += "...";
  }
  return text;
}

// Compares tokens without stopping at the first differing byte.
bool same_token(const std::string& given, const std::string& expected) {
  if (given.size() != expected.size()) return false;
  unsigned diff = 0;
  for (std::size_t i = 0; i < given.size(); ++i) {
    diff |= static_cast<unsigned char>(given[i]) ^ static_cast<unsigned char>(expected[i]);
  }
  return diff == 0;
}

// Whether something accepts connections on the Unix socket at path (non-blocking probe).
bool unix_socket_is_live(const std::string& path) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    throw InputError("cannot create a socket to probe " + path + ": " + std::strerror(errno));
  }
  sockaddr_un sa{};
  sa.sun_family = AF_UNIX;
  std::memcpy(sa.sun_path, path.data(), path.size());
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&sa), sizeof sa);
  const int err = errno;
  ::close(fd);
  if (rc == 0 || err == EAGAIN || err == EINPROGRESS) return true;  // EAGAIN: backlog full
  if (err == ECONNREFUSED) return false;
  throw InputError("cannot tell whether " + path + " is in use (" + std::strerror(err) +
                   "); remove it by hand if no service is running");
}

}  // namespace

// What the server and its connections share; outlives ControlServer while handlers are pending.
struct ControlServer::State {
  State(asio::io_context& io_context, ControlHandler& h, const ServerOptions& o)
      : io(io_context), acceptor(io_context), accept_retry(io_context), handler(h), options(o) {}

  asio::io_context& io;
  asio::basic_socket_acceptor<SocketProtocol> acceptor;
  asio::steady_timer accept_retry;
  ControlHandler& handler;
  const ServerOptions options;
  bool tcp = true;
  bool closed = false;
  std::string unix_path;  // the socket file this server created, removed on close
  dev_t unix_dev = 0;
  ino_t unix_ino = 0;
  std::unordered_set<std::shared_ptr<Connection>> live;
  std::atomic<std::size_t> count{0};
};

namespace {

using State = ControlServer::State;

// One client: a read loop splitting lines, a write queue, and an optional status stream.
class Connection : public std::enable_shared_from_this<Connection> {
 public:
  Connection(std::shared_ptr<State> server, SocketProtocol::socket socket)
      : server_(std::move(server)), socket_(std::move(socket)), timer_(server_->io) {}

  // Starts the read loop.
  void start() { read(); }
  // Closes the socket at once and leaves the server's set; pending handlers then do nothing.
  void close();

 private:
  void read();
  void on_read(const error_code& ec, std::size_t bytes);
  void consume(const char* data, std::size_t size);
  void on_line(std::string_view line);
  Json answer(std::string_view line, std::optional<double>& subscribe_hz);
  void start_stream(double hz);
  void stop_stream();
  void tick(std::uint64_t stream);
  void send(std::string bytes);
  void write_front();
  void on_written(const error_code& ec);

  std::shared_ptr<State> server_;
  SocketProtocol::socket socket_;
  asio::steady_timer timer_;
  std::array<char, kReadChunkBytes> buffer_{};
  std::string line_;         // the request line read so far
  bool discarding_ = false;  // inside an oversized line, up to its newline
  bool reading_ = false;     // an async_read_some is pending
  bool read_eof_ = false;    // the client has closed its side
  bool closed_ = false;
  std::deque<std::string> out_;  // front() is being written when writing_
  std::size_t queued_bytes_ = 0;
  bool writing_ = false;
  std::uint64_t stream_ = 0;  // current status stream; bumped when one stops
  bool streaming_ = false;
  Clock::duration period_{};
  Clock::time_point next_tick_{};
};

// Starts one async_read_some unless one is pending, the client is done, or replies pile up.
void Connection::read() {
  if (closed_ || reading_ || read_eof_ || queued_bytes_ > kMaxQueuedBytes) return;
  reading_ = true;
  socket_.async_read_some(asio::buffer(buffer_),
                          [self = shared_from_this()](const error_code& ec, std::size_t bytes) {
                            self->on_read(ec, bytes);
                          });
}

// Splits what arrived into lines; at end of stream answers the last line, flushes, closes.
void Connection::on_read(const error_code& ec, std::size_t bytes) {
  reading_ = false;
  if (closed_) return;
  if (ec == asio::error::eof) {
    read_eof_ = true;
    stop_stream();
    if (!line_.empty() && !discarding_) on_line(std::exchange(line_, {}));
    if (!closed_ && !writing_ && out_.empty()) close();
    return;
  }
  if (ec) return close();
  consume(buffer_.data(), bytes);
  read();
}

// Appends bytes to the current line, answering each complete one and cutting oversized ones.
void Connection::consume(const char* data, std::size_t size) {
  const std::size_t max = server_->options.max_line_bytes;
  while (size > 0 && !closed_) {
    const auto* newline = static_cast<const char*>(std::memchr(data, '\n', size));
    const std::size_t take = newline ? static_cast<std::size_t>(newline - data) : size;
    if (!discarding_ && line_.size() + take > max) {
      discarding_ = true;
      line_ = std::string();
      stop_stream();
      send(to_line(error_reply("the request line is longer than " + std::to_string(max) +
                               " bytes and was discarded; send shorter requests, one per line")));
    } else if (!discarding_) {
      line_.append(data, take);
    }
    if (!newline) return;
    data += take + 1;
    size -= take + 1;
    if (std::exchange(discarding_, false)) continue;
    on_line(std::exchange(line_, {}));
  }
}

// Ends any status stream, then answers one line (blank lines get no reply).
void Connection::on_line(std::string_view line) {
  stop_stream();
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (line.find_first_not_of(" \t\r") == std::string_view::npos) return;
  std::optional<double> subscribe_hz;
  const Json reply = answer(line, subscribe_hz);
  if (closed_) return;  // the handler closed the server
  send(to_line(reply));
  if (subscribe_hz) start_stream(*subscribe_hz);
}

// The reply to one request line: the checks, then the handler.
Json Connection::answer(std::string_view line, std::optional<double>& subscribe_hz) {
  RequestCheck check = check_request(line, server_->options);
  if (!check.to_handler) {
    subscribe_hz = check.subscribe_hz;
    return std::move(check.reply);
  }
  return handler_reply([this](const Json& r) { return server_->handler.handle(r); }, check.request);
}

// Sends a status line now and then every 1/hz s on absolute deadlines.
void Connection::start_stream(double hz) {
  if (read_eof_) return;  // the client has already closed its side
  period_ = std::max<Clock::duration>(
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / hz)),
      kMinStatusPeriod);
  streaming_ = true;
  next_tick_ = Clock::now();
  tick(stream_);
}

// Stops the status stream; a tick already queued sees the new stream_ and does nothing.
void Connection::stop_stream() {
  if (!streaming_) return;
  streaming_ = false;
  ++stream_;
  timer_.cancel();
}

// One status line (skipped while the client is not reading), then the next deadline.
void Connection::tick(std::uint64_t stream) {
  if (closed_ || !streaming_ || stream != stream_) return;
  if (queued_bytes_ <= kMaxQueuedBytes) {
    std::string line;
    try {
      line = to_line(server_->handler.status());
    } catch (const std::exception& e) {
      stop_stream();
      return send(to_line(error_reply(std::string("internal error: status: ") + e.what())));
    } catch (...) {
      stop_stream();
      return send(to_line(error_reply("internal error: status: unknown exception")));
    }
    send(std::move(line));
  }
  const auto now = Clock::now();
  next_tick_ += period_;
  if (next_tick_ <= now) next_tick_ = now + period_;  // late: skip, never burst to catch up
  timer_.expires_at(next_tick_);
  timer_.async_wait([self = shared_from_this(), stream](const error_code& ec) {
    if (!ec) self->tick(stream);
  });
}

// Queues bytes and starts writing unless a write is in flight.
void Connection::send(std::string bytes) {
  if (closed_) return;
  queued_bytes_ += bytes.size();
  out_.push_back(std::move(bytes));
  if (!writing_) write_front();
}

// Writes the oldest queued line; the only place that starts an async_write.
void Connection::write_front() {
  writing_ = true;
  asio::async_write(
      socket_, asio::buffer(out_.front()),
      [self = shared_from_this()](const error_code& ec, std::size_t) { self->on_written(ec); });
}

// Drops the written line, writes the next, resumes reading, or closes after end of stream.
void Connection::on_written(const error_code& ec) {
  writing_ = false;
  if (closed_) return;
  if (ec) return close();
  queued_bytes_ -= out_.front().size();
  out_.pop_front();
  if (!out_.empty()) return write_front();
  if (read_eof_) return close();
  read();
}

void Connection::close() {
  if (closed_) return;
  closed_ = true;
  streaming_ = false;
  error_code ignored;
  timer_.cancel();
  socket_.shutdown(SocketProtocol::socket::shutdown_both, ignored);
  socket_.close(ignored);
  if (server_->live.erase(shared_from_this()) > 0) --server_->count;
}

// Accepts connections until the acceptor closes; retries after a pause on errors like EMFILE.
void accept_next(const std::shared_ptr<State>& state) {
  state->acceptor.async_accept([state](const error_code& ec, SocketProtocol::socket socket) {
    if (state->closed || ec == asio::error::operation_aborted) return;
    if (ec) {
      state->accept_retry.expires_after(kAcceptRetry);
      state->accept_retry.async_wait([state](const error_code& wait_ec) {
        if (!wait_ec && !state->closed) accept_next(state);
      });
      return;
    }
    error_code ignored;
    if (state->tcp) socket.set_option(asio::ip::tcp::no_delay(true), ignored);
    const auto connection = std::make_shared<Connection>(state, std::move(socket));
    state->live.insert(connection);
    ++state->count;
    connection->start();
    accept_next(state);
  });
}

// Opens, binds and (after prepare, which may set file permissions) listens, or throws.
template <typename Prepare>
void listen_at(State& state, const SocketProtocol::endpoint& endpoint, const std::string& name,
               bool reuse_address, Prepare prepare) {
  error_code ec;
  state.acceptor.open(endpoint.protocol(), ec);
  if (!ec && reuse_address) state.acceptor.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) state.acceptor.bind(endpoint, ec);
  if (!ec) prepare();
  if (!ec) state.acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    error_code ignored;
    state.acceptor.close(ignored);
    throw InputError("cannot listen on " + name + ": " + ec.message() +
                     "; choose another address or stop the process that holds it");
  }
}

}  // namespace

namespace {

// Checks "hz" of a subscribe request; sets subscribe_hz when it is acceptable.
Json subscribe_reply(const Json& request, const ServerOptions& options,
                     std::optional<double>& subscribe_hz) {
  const double max_hz = options.max_subscribe_hz;
  const std::string range = "at least " + number_text(options.min_subscribe_hz) + " and at most " +
                            number_text(max_hz) + " (docs/input-ranges.md)";
  const auto hz = request.find("hz");
  if (hz == request.end() || !hz->is_number()) {
    return error_reply("subscribe needs \"hz\", the number of status lines per second, " + range +
                       ", such as {\"cmd\":\"subscribe\",\"hz\":10}");
  }
  const double value = hz->get<double>();
  if (!(value >= options.min_subscribe_hz && value <= max_hz)) {
    return error_reply("\"hz\" = " + number_text(value) + " is out of range: it must be " + range);
  }
  subscribe_hz = value;
  return {{"ok", true}};
}

}  // namespace

// The checks of one request line, in the order described at the top.
RequestCheck check_request(std::string_view line, const ServerOptions& options) {
  RequestCheck out;
  const auto reject = [&](std::string message) {
    out.reply = error_reply(std::move(message));
    return out;
  };
  Json request;
  try {
    request = parse_json_input(line, "the request",
                               "send one JSON object per line, such as {\"cmd\":\"status\"}");
  } catch (const InputError& e) {
    return reject(clip(e.what()));
  }
  if (!request.is_object()) {
    return reject(std::string("the request is a JSON ") + request.type_name() +
                  ", not an object; send one object per line, such as {\"cmd\":\"status\"}");
  }
  if (const auto& token = options.token) {
    const auto given = request.find("token");
    if (given == request.end() || !given->is_string()) {
      return reject(
          "this server requires a string \"token\" in every request; add the token from the "
          "service config");
    }
    if (!same_token(given->get_ref<const std::string&>(), *token)) {
      return reject("the \"token\" is wrong; use the token from the service config");
    }
  }
  const auto cmd = request.find("cmd");
  if (cmd == request.end()) {
    return reject("the request has no \"cmd\"; add one, such as {\"cmd\":\"status\"}");
  }
  if (!cmd->is_string()) {
    return reject(std::string("\"cmd\" is a JSON ") + cmd->type_name() +
                  "; it must be a string, such as \"status\"");
  }
  if (*cmd == "subscribe") {
    out.reply = subscribe_reply(request, options, out.subscribe_hz);
    return out;
  }
  out.to_handler = true;
  out.request = std::move(request);
  return out;
}

ListenAddress ListenAddress::parse(const std::string& text) {
  ListenAddress address;
  if (text.rfind("unix:", 0) == 0) {
    address.kind = Kind::Unix;
    address.path = text.substr(5);
    if (address.path.empty()) bad_address(text, "the socket path is empty");
    if (address.path.find('\0') != std::string::npos) bad_address(text, "the path has a NUL byte");
    constexpr std::size_t kMaxPath = sizeof(sockaddr_un{}.sun_path) - 1;
    if (address.path.size() > kMaxPath) {
      bad_address(text, "the socket path has " + std::to_string(address.path.size()) +
                            " bytes, the limit is " + std::to_string(kMaxPath));
    }
    return address;
  }
  if (text.rfind("tcp:", 0) != 0) bad_address(text, "it starts with neither tcp: nor unix:");
  const std::string rest = text.substr(4);
  std::string port_text;
  error_code ec;
  if (!rest.empty() && rest[0] == '[') {
    const auto bracket = rest.find(']');
    if (bracket == std::string::npos) bad_address(text, "the IPv6 address has no closing ']'");
    if (bracket + 1 >= rest.size() || rest[bracket + 1] != ':') {
      bad_address(text, "':PORT' must follow the ']'");
    }
    address.host = rest.substr(1, bracket - 1);
    port_text = rest.substr(bracket + 2);
    asio::ip::make_address_v6(address.host, ec);
    if (ec) bad_address(text, "'" + address.host + "' is not an IPv6 address");
  } else {
    const auto colon = rest.rfind(':');
    if (colon == std::string::npos) bad_address(text, "the port is missing");
    address.host = rest.substr(0, colon);
    port_text = rest.substr(colon + 1);
    if (address.host.find(':') != std::string::npos) {
      bad_address(text, "an IPv6 address goes in brackets, as in tcp:[::1]:PORT");
    }
    if (address.host != "localhost") {
      asio::ip::make_address_v4(address.host, ec);
      if (ec) {
        bad_address(text,
                    "'" + address.host +
                        "' is neither an IPv4 address nor localhost (names are not resolved)");
      }
    }
  }
  unsigned value = 0;
  const char* end = port_text.data() + port_text.size();
  const auto [stop, err] = std::from_chars(port_text.data(), end, value);
  if (port_text.empty() || err != std::errc() || stop != end || value > 65535) {
    bad_address(text, "the port '" + port_text + "' is not a number from 0 to 65535");
  }
  address.port = static_cast<std::uint16_t>(value);
  return address;
}

bool ListenAddress::is_loopback() const {
  if (kind == Kind::Unix || host == "localhost") return true;
  error_code ec;
  const auto ip = asio::ip::make_address(host, ec);
  if (ec) return false;
  if (ip.is_v6() && ip.to_v6().is_v4_mapped()) {
    return asio::ip::make_address_v4(asio::ip::v4_mapped, ip.to_v6()).is_loopback();
  }
  return ip.is_loopback();
}

std::string ListenAddress::to_string() const {
  if (kind == Kind::Unix) return "unix:" + path;
  const bool v6 = host.find(':') != std::string::npos;
  return "tcp:" + (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

ControlServer::ControlServer(boost::asio::io_context& io, const ListenAddress& address,
                             ControlHandler& handler, const ServerOptions& options)
    : state_(std::make_shared<State>(io, handler, options)) {
  if (options.max_line_bytes == 0) {
    throw InputError("max_line_bytes = 0 is invalid: it must be at least 1 (default 65536)");
  }
  require_positive("max_subscribe_hz", options.max_subscribe_hz);
  require_positive("min_subscribe_hz", options.min_subscribe_hz);
  if (options.min_subscribe_hz > options.max_subscribe_hz) {
    throw InputError("min_subscribe_hz is above max_subscribe_hz; swap them");
  }
  if (options.token && options.token->empty()) {
    throw InputError("the control token is empty; set a non-empty token or remove it");
  }
  const std::string name = address.to_string();
  if (address.kind == ListenAddress::Kind::Tcp) {
    if (!address.is_loopback() && !options.token) {
      throw InputError("listen address " + name +
                       " is not loopback, so other hosts could drive the machine; set a control "
                       "token in the config, or listen on tcp:127.0.0.1:PORT or unix:PATH");
    }
    error_code ec;
    const auto ip = address.host == "localhost"
                        ? asio::ip::address(asio::ip::address_v4::loopback())
                        : asio::ip::make_address(address.host, ec);
    if (ec) throw InputError("listen address " + name + " has no valid IP address");
    listen_at(*state_, SocketProtocol::endpoint(asio::ip::tcp::endpoint(ip, address.port)), name,
              true, [] {});
    const SocketProtocol::endpoint bound = state_->acceptor.local_endpoint(ec);
    asio::ip::tcp::endpoint tcp_bound;
    if (!ec && bound.size() <= tcp_bound.capacity()) {
      std::memcpy(tcp_bound.data(), bound.data(), bound.size());
      tcp_bound.resize(bound.size());
      port_ = tcp_bound.port();
    }
  } else {
    state_->tcp = false;
    const std::string& path = address.path;
    if (path.empty() || path.size() >= sizeof(sockaddr_un{}.sun_path)) {
      throw InputError("the Unix socket path '" + path + "' must have 1 to " +
                       std::to_string(sizeof(sockaddr_un{}.sun_path) - 1) + " bytes");
    }
    struct stat st {};
    if (::lstat(path.c_str(), &st) == 0) {
      if (!S_ISSOCK(st.st_mode)) {
        throw InputError(path + " exists and is not a socket; remove it or choose another " +
                         "unix:PATH");
      }
      if (unix_socket_is_live(path)) {
        throw InputError("another process is listening on " + path +
                         "; stop it or choose another unix:PATH");
      }
      if (::unlink(path.c_str()) != 0 && errno != ENOENT) {
        throw InputError("cannot remove the stale socket " + path + ": " + std::strerror(errno));
      }
    }
    const SocketProtocol::endpoint endpoint{asio::local::stream_protocol::endpoint(path)};
    listen_at(*state_, endpoint, name, false, [&] {
      // Before listen(), so no client connects while the file still has the umask's mode.
      if (::chmod(path.c_str(), 0660) != 0 || ::lstat(path.c_str(), &st) != 0) {
        const std::string why = std::strerror(errno);
        ::unlink(path.c_str());
        error_code ignored;
        state_->acceptor.close(ignored);
        throw InputError("cannot set permissions 0660 on " + path + ": " + why);
      }
      state_->unix_path = path;
      state_->unix_dev = st.st_dev;
      state_->unix_ino = st.st_ino;
    });
  }
  accept_next(state_);
}

ControlServer::~ControlServer() {
  close();
}

void ControlServer::close() {
  State& state = *state_;
  if (state.closed) return;
  state.closed = true;
  if (!state.unix_path.empty()) {
    struct stat st {};
    // Only the file this server made: another service may have replaced a stale one.
    if (::lstat(state.unix_path.c_str(), &st) == 0 && st.st_dev == state.unix_dev &&
        st.st_ino == state.unix_ino) {
      ::unlink(state.unix_path.c_str());
    }
    state.unix_path.clear();
  }
  error_code ignored;
  state.acceptor.close(ignored);
  state.accept_retry.cancel();
  const auto live = std::exchange(state.live, {});
  for (const auto& connection : live) connection->close();
  state.count = 0;
}

std::size_t ControlServer::connections() const {
  return state_->count.load();
}

Json error_reply(std::string message) {
  return {{"ok", false}, {"error", std::move(message)}};
}

Json handler_reply(const std::function<Json(const Json&)>& call, const Json& request) {
  Json reply;
  try {
    reply = call(request);
  } catch (const InputError& e) {
    return error_reply(e.what());
  } catch (const std::exception& e) {
    return error_reply(std::string("internal error: ") + e.what());
  } catch (...) {
    return error_reply("internal error: unknown exception");
  }
  if (!reply.is_object()) {
    return error_reply(std::string("internal error: the reply is a JSON ") + reply.type_name() +
                       ", not an object");
  }
  const auto ok = reply.find("ok");
  if (ok == reply.end()) {
    reply["ok"] = true;
  } else if (!ok->is_boolean()) {
    return error_reply("internal error: the reply's \"ok\" is not true or false");
  } else if (!ok->get<bool>() && !reply.contains("error")) {
    reply["error"] = "the request failed and the service gave no reason";
  }
  return reply;
}

}  // namespace ncd::comms
