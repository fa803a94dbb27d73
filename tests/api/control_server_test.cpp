// Control socket server over real sockets: loopback TCP on port 0 and Unix sockets in a temporary
// folder. The server runs on an io_context thread; clients are plain blocking POSIX sockets with
// poll() timeouts, independent of Asio.
#include "api/control_server.hpp"

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/post.hpp>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <optional>
#include <thread>
#include <vector>

#include "core/error.hpp"

namespace ncd::comms {
namespace {

using Json = nlohmann::json;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// Echoes "echo", throws for "refuse"/"crash", returns odd replies for "array"/"silent_fail".
class TestHandler : public ControlHandler {
 public:
  Json handle(const Json& request) override {
    ++handled;
    const auto cmd = request.at("cmd").get<std::string>();
    if (cmd == "echo") return {{"echo", request}};
    if (cmd == "refuse") throw InputError("percent = 300 is above the limit 150; send at most 150");
    if (cmd == "crash") throw std::runtime_error("boom");
    if (cmd == "array") return Json::array({1, 2});
    if (cmd == "silent_fail") return {{"ok", false}};
    throw InputError("unknown command '" + cmd + "'");
  }
  Json status() override { return {{"seq", statuses++}}; }

  std::atomic<int> handled{0};
  std::atomic<int> statuses{0};
};

// A blocking client socket with timeouts on every read.
class Client {
 public:
  static Client tcp(std::uint16_t port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in sa{};
    sa.sin_family = AF_INET;
    sa.sin_port = htons(port);
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connect_or_fail(fd, reinterpret_cast<const sockaddr*>(&sa), sizeof sa);
    return Client(fd);
  }
  static Client unix_socket(const std::string& path) {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    std::memcpy(sa.sun_path, path.data(), path.size());
    connect_or_fail(fd, reinterpret_cast<const sockaddr*>(&sa), sizeof sa);
    return Client(fd);
  }
  Client(Client&& other) noexcept : fd_(std::exchange(other.fd_, -1)), buf_(other.buf_) {}
  Client& operator=(Client&&) = delete;
  ~Client() {
    if (fd_ >= 0) ::close(fd_);
  }

  // Sends all bytes.
  void send(std::string_view bytes) const {
    while (!bytes.empty()) {
      const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
      if (n <= 0) throw std::runtime_error(std::string("send: ") + std::strerror(errno));
      bytes.remove_prefix(static_cast<std::size_t>(n));
    }
  }
  // The next line without its newline; nullopt on timeout or end of stream.
  std::optional<std::string> line(std::chrono::milliseconds timeout = 5000ms) {
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      if (const auto nl = buf_.find('\n'); nl != std::string::npos) {
        std::string out = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return out;
      }
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      if (left <= 0ms) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) return std::nullopt;
      char chunk[4096];
      const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
      if (n <= 0) return std::nullopt;
      buf_.append(chunk, static_cast<std::size_t>(n));
    }
  }
  // The next line as JSON (null on timeout).
  Json json(std::chrono::milliseconds timeout = 5000ms) {
    const auto text = line(timeout);
    return text ? Json::parse(*text) : Json();
  }
  // Sends one request line and returns the next reply.
  Json request(const std::string& text) {
    send(text + "\n");
    return json();
  }
  // True when the server closes the stream within the timeout (with nothing else unread).
  bool sees_eof(std::chrono::milliseconds timeout = 5000ms) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout.count())) <= 0) return false;
    char c;
    return ::recv(fd_, &c, 1, 0) == 0;
  }
  void shutdown_write() const { ::shutdown(fd_, SHUT_WR); }
  // Closes with a reset (SO_LINGER 0), the rudest way a client can leave.
  void reset() {
    linger l{1, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &l, sizeof l);
    ::close(std::exchange(fd_, -1));
  }

 private:
  explicit Client(int fd) : fd_(fd) {}
  static void connect_or_fail(int fd, const sockaddr* sa, socklen_t size) {
    if (fd < 0 || ::connect(fd, sa, size) != 0) {
      const std::string why = std::strerror(errno);
      if (fd >= 0) ::close(fd);
      throw std::runtime_error("connect: " + why);
    }
  }
  int fd_;
  std::string buf_;
};

// A server with its io_context running on a thread; closed on the I/O thread at the end.
class Running {
 public:
  explicit Running(const std::string& address, ServerOptions options = {})
      : server_(io_, ListenAddress::parse(address), handler, options),
        thread_([this] { io_.run(); }) {}
  ~Running() { stop(); }

  // Closes the server on the I/O thread and joins it.
  void stop() {
    if (!thread_.joinable()) return;
    std::promise<void> closed;
    boost::asio::post(io_, [&] {
      server_.close();
      closed.set_value();
    });
    closed.get_future().wait();
    work_.reset();
    io_.stop();
    thread_.join();
  }
  std::uint16_t port() const { return server_.port(); }
  std::size_t connections() const { return server_.connections(); }
  Client client() { return Client::tcp(port()); }

  TestHandler handler;

 private:
  boost::asio::io_context io_;
  boost::asio::executor_work_guard<boost::asio::io_context::executor_type> work_ =
      boost::asio::make_work_guard(io_);
  ControlServer server_;
  std::thread thread_;
};

// A fresh temporary folder, removed at the end.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "ncd_comms_XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

// Waits up to 5 s for a condition checked from the test thread.
template <typename Condition>
bool eventually(Condition condition) {
  const auto deadline = Clock::now() + 5s;
  while (!condition()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(5ms);
  }
  return true;
}

// Expects an error reply whose message contains part.
void expect_error(const Json& reply, const std::string& part) {
  ASSERT_TRUE(reply.is_object()) << reply;
  EXPECT_EQ(reply.value("ok", true), false) << reply;
  ASSERT_TRUE(reply.contains("error") && reply["error"].is_string()) << reply;
  EXPECT_NE(reply["error"].get<std::string>().find(part), std::string::npos)
      << "'" << part << "' not in: " << reply["error"];
}

// Expects the echo of a request {"cmd":"echo","n":n}.
void expect_echo(const Json& reply, int n) {
  ASSERT_TRUE(reply.is_object()) << reply;
  EXPECT_EQ(reply.value("ok", false), true) << reply;
  ASSERT_TRUE(reply.contains("echo")) << reply;
  EXPECT_EQ(reply["echo"].value("n", -1), n) << reply;
}

std::string echo(int n) {
  return Json{{"cmd", "echo"}, {"n", n}}.dump();
}

TEST(ControlServerTest, RoundTripOverTcpAddsOk) {
  Running server("tcp:127.0.0.1:0");
  EXPECT_NE(server.port(), 0);
  Client client = server.client();
  const Json reply = client.request(R"({"cmd":"echo","n":7,"name":"x"})");
  expect_echo(reply, 7);
  EXPECT_EQ(reply["echo"]["name"], "x");
  EXPECT_TRUE(eventually([&] { return server.connections() == 1; }));
  EXPECT_EQ(server.handler.handled, 1);
}

TEST(ControlServerTest, SeveralRequestsInOneSendPipelinedAndSplit) {
  Running server("tcp:127.0.0.1:0");
  Client client = server.client();
  client.send(echo(1) + "\n" + echo(2) + "\r\n" + echo(3) + "\n");
  for (int n = 1; n <= 3; ++n) expect_echo(client.json(), n);

  const std::string request = echo(4) + "\n";  // one byte per send
  for (char c : request) client.send(std::string(1, c));
  expect_echo(client.json(), 4);

  for (int n = 5; n < 105; ++n) client.send(echo(n) + "\n");  // pipelined without reading
  for (int n = 5; n < 105; ++n) expect_echo(client.json(), n);
}

TEST(ControlServerTest, MalformedRequestsGetErrorsAndTheConnectionGoesOn) {
  Running server("tcp:127.0.0.1:0");
  Client client = server.client();
  expect_error(client.request("{cmd"), "not valid JSON");
  expect_error(client.request("\x01\xff\xfe garbage \xc3"), "not valid JSON");
  expect_error(client.request("[1,2]"), "not an object");
  expect_error(client.request("\"status\""), "not an object");
  expect_error(client.request(R"({"percent":50})"), "no \"cmd\"");
  expect_error(client.request(R"({"cmd":5})"), "must be a string");
  expect_error(client.request(R"({"cmd":null})"), "must be a string");
  expect_error(client.request(R"({"cmd":"subscribe"})"), "needs \"hz\"");
  expect_error(client.request(R"({"cmd":"subscribe","hz":"fast"})"), "needs \"hz\"");
  expect_error(client.request(R"({"cmd":"subscribe","hz":0})"), "out of range");
  expect_error(client.request(R"({"cmd":"subscribe","hz":-3})"), "out of range");
  expect_error(client.request(R"({"cmd":"subscribe","hz":5000})"), "at most 1000");
  // A tiny rate would leave a subscriber waiting for days: the bound is 0.1 Hz.
  expect_error(client.request(R"({"cmd":"subscribe","hz":1e-10})"), "at least 0.1");
  expect_error(client.request(R"({"cmd":"subscribe","hz":0.009})"), "at least 0.1");
  EXPECT_EQ(server.handler.handled, 0);  // none of these reached the handler
  client.send("\n   \r\n");              // blank lines: no request, no reply
  expect_echo(client.request(echo(1)), 1);
  expect_error(client.request(R"({"cmd":"jump"})"), "unknown command 'jump'");
  expect_echo(client.request(echo(2)), 2);
  EXPECT_EQ(server.handler.handled, 3);
}

TEST(ControlServerTest, HandlerErrorsBecomeWellFormedReplies) {
  Running server("tcp:127.0.0.1:0");
  Client client = server.client();
  const Json refused = client.request(R"({"cmd":"refuse"})");
  expect_error(refused, "");
  EXPECT_EQ(refused["error"], "percent = 300 is above the limit 150; send at most 150");
  expect_error(client.request(R"({"cmd":"crash"})"), "internal error: boom");
  expect_error(client.request(R"({"cmd":"array"})"), "internal error");
  expect_error(client.request(R"({"cmd":"silent_fail"})"), "no reason");
  expect_echo(client.request(echo(1)), 1);
}

TEST(ControlServerTest, OversizedLineGetsOneErrorAndIsSkipped) {
  Running server("tcp:127.0.0.1:0");  // max_line_bytes 65536
  Client client = server.client();
  const std::string big = R"({"cmd":"echo","pad":")" + std::string(100 * 1024, 'x') + "\"}";
  client.send(big + "\n" + echo(1) + "\n");
  expect_error(client.json(), "longer than 65536 bytes");
  expect_echo(client.json(), 1);  // the oversized line gave exactly one reply
  EXPECT_EQ(server.handler.handled, 1);
}

TEST(ControlServerTest, LineLimitIsExactInBytes) {
  ServerOptions options;
  options.max_line_bytes = 64;
  Running server("tcp:127.0.0.1:0", options);
  Client client = server.client();
  const auto padded = [](std::size_t size) {
    std::string line = R"({"cmd":"echo","n":1,"p":""})";
    line.insert(line.size() - 2, size - line.size(), 'p');
    return line;
  };
  ASSERT_EQ(padded(64).size(), 64u);
  expect_echo(client.request(padded(64)), 1);
  client.send(padded(65) + "\n" + padded(64) + "\n" + padded(200) + "\n");
  expect_error(client.json(), "longer than 64 bytes");
  expect_echo(client.json(), 1);
  expect_error(client.json(), "longer than 64 bytes");
  expect_echo(client.request(echo(2)), 2);
  EXPECT_EQ(server.handler.handled, 3);
}

TEST(ControlServerTest, SubscribeStreamsAtTheRateAndStopsOnTheNextRequest) {
  Running server("tcp:127.0.0.1:0");
  Client client = server.client();
  // 16 lines: at 50 Hz the 16th is sent at least 15 periods (300 ms) after the request. A loaded
  // machine only makes them later, so the rate is checked from below in time, from before the
  // request, never by how many lines a fixed window happened to see.
  const auto asked = Clock::now();
  const Json ok = client.request(R"({"cmd":"subscribe","hz":50})");
  EXPECT_EQ(ok, Json({{"ok", true}}));
  int last_seq = -1;
  for (int lines = 0; lines < 16; ++lines) {
    const auto line = client.line(5s);
    ASSERT_TRUE(line) << "no status line within 5 s after " << lines;
    const Json status = Json::parse(*line);
    ASSERT_TRUE(status.contains("seq")) << status;
    EXPECT_GT(status["seq"].get<int>(), last_seq);
    last_seq = status["seq"].get<int>();
  }
  const double span_s = std::chrono::duration<double>(Clock::now() - asked).count();
  EXPECT_GE(span_s, 15 * 0.020 * 0.9) << "16 lines faster than 50 Hz: the rate was not honoured";
  std::cout << "[ measured ] 16 status lines " << span_s << " s after the request\n";

  client.send(echo(9) + "\n");
  Json reply = client.json();
  while (reply.contains("seq")) reply = client.json();  // lines sent before the request arrived
  expect_echo(reply, 9);
  EXPECT_FALSE(client.line(300ms)) << "the stream goes on after a new request";
  expect_echo(client.request(echo(10)), 10);
}

TEST(ControlServerTest, ClientLeavingMidSubscribeDoesNotDisturbOthers) {
  Running server("tcp:127.0.0.1:0");
  Client watcher = server.client();
  ASSERT_EQ(watcher.request(R"({"cmd":"subscribe","hz":20})"), Json({{"ok", true}}));
  {
    Client fast = server.client();
    ASSERT_EQ(fast.request(R"({"cmd":"subscribe","hz":1000})"), Json({{"ok", true}}));
    ASSERT_TRUE(fast.line());
    Client closer = server.client();
    ASSERT_EQ(closer.request(R"({"cmd":"subscribe","hz":1000})"), Json({{"ok", true}}));
    ASSERT_TRUE(closer.line());
    EXPECT_TRUE(eventually([&] { return server.connections() == 3; }));
    fast.reset();  // RST mid-stream
  }                // closer: an orderly close mid-stream
  EXPECT_TRUE(eventually([&] { return server.connections() == 1; }));
  int lines = 0;
  const auto end = Clock::now() + 300ms;
  while (Clock::now() < end && watcher.line(300ms)) ++lines;
  EXPECT_GE(lines, 2) << "the remaining subscriber still streams";
  watcher.send(echo(1) + "\n");
  Json reply = watcher.json();
  while (reply.contains("seq")) reply = watcher.json();
  expect_echo(reply, 1);
  Client late = server.client();
  expect_echo(late.request(echo(2)), 2);
}

TEST(ControlServerTest, HalfClosedClientStillGetsItsReplies) {
  Running server("tcp:127.0.0.1:0");
  Client client = server.client();
  client.send(echo(1) + "\n" + echo(2));  // the last line has no newline
  client.shutdown_write();
  expect_echo(client.json(), 1);
  expect_echo(client.json(), 2);
  EXPECT_TRUE(client.sees_eof());
  EXPECT_TRUE(eventually([&] { return server.connections() == 0; }));
}

TEST(ControlServerTest, ManyConcurrentClients) {
  Running server("tcp:127.0.0.1:0");
  std::vector<Client> clients;
  for (int i = 0; i < 20; ++i) clients.push_back(server.client());
  for (int round = 0; round < 10; ++round) {
    for (int i = 0; i < 20; ++i)
      clients[static_cast<std::size_t>(i)].send(echo(100 * i + round) + "\n");
  }
  for (int i = 0; i < 20; ++i) {
    for (int round = 0; round < 10; ++round) {
      expect_echo(clients[static_cast<std::size_t>(i)].json(), 100 * i + round);
    }
  }
  EXPECT_EQ(server.connections(), 20u);
  EXPECT_EQ(server.handler.handled, 200);
}

TEST(ControlServerTest, ClientThatDoesNotReadIsThrottledNotBuffered) {
  TempDir dir;
  const std::string path = dir.file("control.sock");
  Running server("unix:" + path);
  Client client = Client::unix_socket(path);
  constexpr int kRequests = 200;  // 10 MB of requests, each echoed back in full
  const std::string pad(50 * 1000, 'p');
  std::thread sender([&] {
    for (int n = 0; n < kRequests; ++n) {
      client.send(Json{{"cmd", "echo"}, {"n", n}, {"pad", pad}}.dump() + "\n");
    }
  });
  std::this_thread::sleep_for(500ms);
  // Unbounded queueing would have answered all 200; the server stops reading once ~1 MB of
  // replies wait, and the Unix socket buffers hold little more.
  const int answered_unread = server.handler.handled;
  EXPECT_LT(answered_unread, kRequests / 2);
  for (int n = 0; n < kRequests; ++n) expect_echo(client.json(), n);
  sender.join();
  EXPECT_EQ(server.handler.handled, kRequests);
}

TEST(ControlServerTest, TokenIsRequiredAndChecked) {
  ServerOptions options;
  options.token = "s3cret";
  Running server("tcp:127.0.0.1:0", options);
  Client client = server.client();
  expect_error(client.request(echo(1)), "requires a string \"token\"");
  expect_error(client.request(R"({"cmd":"echo","n":1,"token":42})"), "requires a string \"token\"");
  expect_error(client.request(R"({"cmd":"echo","n":1,"token":"s3creT"})"), "token\" is wrong");
  expect_error(client.request(R"({"cmd":"echo","n":1,"token":"s3cret!"})"), "token\" is wrong");
  expect_error(client.request(R"({"cmd":"subscribe","hz":10})"), "token");
  EXPECT_EQ(server.handler.handled, 0);
  expect_echo(client.request(R"({"cmd":"echo","n":1,"token":"s3cret"})"), 1);
  EXPECT_EQ(client.request(R"({"cmd":"subscribe","hz":10,"token":"s3cret"})"),
            Json({{"ok", true}}));
  EXPECT_TRUE(client.json().contains("seq"));
}

TEST(ControlServerTest, NonLoopbackNeedsAToken) {
  boost::asio::io_context io;
  TestHandler handler;
  try {
    ControlServer server(io, ListenAddress::parse("tcp:0.0.0.0:0"), handler, {});
    FAIL() << "a server on 0.0.0.0 without a token was created";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tcp:0.0.0.0:0 is not loopback"), std::string::npos)
        << e.what();
  }
  ServerOptions options;
  options.token = "";
  EXPECT_THROW(ControlServer(io, ListenAddress::parse("tcp:0.0.0.0:0"), handler, options),
               InputError);  // an empty token is no token
  options.token = "s3cret";
  ControlServer server(io, ListenAddress::parse("tcp:0.0.0.0:0"), handler, options);
  EXPECT_NE(server.port(), 0);
}

TEST(ControlServerTest, InvalidOptionsAreRefused) {
  boost::asio::io_context io;
  TestHandler handler;
  ServerOptions options;
  options.max_line_bytes = 0;
  EXPECT_THROW(ControlServer(io, ListenAddress::parse("tcp:127.0.0.1:0"), handler, options),
               InputError);
  options = {};
  options.max_subscribe_hz = 0;
  EXPECT_THROW(ControlServer(io, ListenAddress::parse("tcp:127.0.0.1:0"), handler, options),
               InputError);
}

TEST(ControlServerTest, PortInUseIsAnInputError) {
  Running first("tcp:127.0.0.1:0");
  boost::asio::io_context io;
  TestHandler handler;
  const auto address = ListenAddress::parse("tcp:127.0.0.1:" + std::to_string(first.port()));
  EXPECT_THROW(ControlServer(io, address, handler, {}), InputError);
  expect_echo(first.client().request(echo(1)), 1);
}

TEST(ControlServerTest, ListenAddressParsesTheAcceptedForms) {
  const auto v4 = ListenAddress::parse("tcp:127.0.0.1:5000");
  EXPECT_EQ(v4.kind, ListenAddress::Kind::Tcp);
  EXPECT_EQ(v4.host, "127.0.0.1");
  EXPECT_EQ(v4.port, 5000);
  EXPECT_TRUE(v4.is_loopback());
  EXPECT_EQ(v4.to_string(), "tcp:127.0.0.1:5000");

  const auto v6 = ListenAddress::parse("tcp:[::1]:65535");
  EXPECT_EQ(v6.host, "::1");
  EXPECT_EQ(v6.port, 65535);
  EXPECT_TRUE(v6.is_loopback());
  EXPECT_EQ(v6.to_string(), "tcp:[::1]:65535");

  const auto local = ListenAddress::parse("tcp:localhost:0");
  EXPECT_EQ(local.host, "localhost");
  EXPECT_EQ(local.port, 0);
  EXPECT_TRUE(local.is_loopback());

  const auto unix_socket = ListenAddress::parse("unix:/run/ncd/control.sock");
  EXPECT_EQ(unix_socket.kind, ListenAddress::Kind::Unix);
  EXPECT_EQ(unix_socket.path, "/run/ncd/control.sock");
  EXPECT_TRUE(unix_socket.is_loopback());
  EXPECT_EQ(unix_socket.to_string(), "unix:/run/ncd/control.sock");
  EXPECT_EQ(ListenAddress::parse("unix:relative.sock").path, "relative.sock");

  EXPECT_TRUE(ListenAddress::parse("tcp:127.8.9.10:1").is_loopback());
  EXPECT_TRUE(ListenAddress::parse("tcp:[::ffff:127.0.0.1]:1").is_loopback());
  EXPECT_FALSE(ListenAddress::parse("tcp:0.0.0.0:1").is_loopback());
  EXPECT_FALSE(ListenAddress::parse("tcp:192.168.1.20:1").is_loopback());
  EXPECT_FALSE(ListenAddress::parse("tcp:[::]:1").is_loopback());
  EXPECT_FALSE(ListenAddress::parse("tcp:[::ffff:10.0.0.1]:1").is_loopback());
  EXPECT_FALSE(ListenAddress::parse("tcp:[fe80::1]:1").is_loopback());
}

TEST(ControlServerTest, ListenAddressErrorsNameTheTextAndTheForms) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "neither tcp: nor unix:"},
      {"udp:127.0.0.1:5", "neither tcp: nor unix:"},
      {"127.0.0.1:5000", "neither tcp: nor unix:"},
      {"tcp:", "port is missing"},
      {"tcp:127.0.0.1", "port is missing"},
      {"tcp:127.0.0.1:", "is not a number from 0 to 65535"},
      {"tcp:127.0.0.1:65536", "'65536' is not a number"},
      {"tcp:127.0.0.1:-1", "'-1' is not a number"},
      {"tcp:127.0.0.1:+1", "'+1' is not a number"},
      {"tcp:127.0.0.1:80x", "'80x' is not a number"},
      {"tcp:127.0.0.1:99999999999", "is not a number"},
      {"tcp::5000", "'' is neither an IPv4 address nor localhost"},
      {"tcp:::1:5000", "IPv6 address goes in brackets"},
      {"tcp:[::1]5000", "':PORT' must follow"},
      {"tcp:[::1", "no closing ']'"},
      {"tcp:[127.0.0.1]:5", "is not an IPv6 address"},
      {"tcp:[]:5", "is not an IPv6 address"},
      {"tcp:example.com:80", "names are not resolved"},
      {"tcp:256.0.0.1:80", "'256.0.0.1' is neither"},
      {"tcp:127.1:80", "'127.1' is neither"},
      {"unix:", "path is empty"},
      {"unix:" + std::string(108, 'a'), "108 bytes, the limit is 107"},
  };
  for (const auto& [text, part] : cases) {
    try {
      ListenAddress::parse(text);
      ADD_FAILURE() << "parsed: " << text;
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("'" + text + "'"), std::string::npos) << what;
      EXPECT_NE(what.find(part), std::string::npos) << "'" << part << "' not in: " << what;
      EXPECT_NE(what.find("tcp:127.0.0.1:PORT"), std::string::npos) << what;
      EXPECT_NE(what.find("unix:PATH"), std::string::npos) << what;
    }
  }
  EXPECT_EQ(ListenAddress::parse("unix:" + std::string(107, 'a')).path.size(), 107u);
}

TEST(ControlServerTest, UnixSocketRoundTripPermissionsAndRemoval) {
  TempDir dir;
  const std::string path = dir.file("control.sock");
  {
    Running server("unix:" + path);
    EXPECT_EQ(server.port(), 0);
    struct stat st {};
    ASSERT_EQ(::lstat(path.c_str(), &st), 0);
    EXPECT_TRUE(S_ISSOCK(st.st_mode));
    EXPECT_EQ(st.st_mode & 07777, 0660u);
    Client client = Client::unix_socket(path);
    expect_echo(client.request(echo(1)), 1);
    EXPECT_EQ(client.request(R"({"cmd":"subscribe","hz":100})"), Json({{"ok", true}}));
    EXPECT_TRUE(client.json().contains("seq"));
    server.stop();
    EXPECT_TRUE(client.sees_eof()) << "close() ends the connections";
    EXPECT_EQ(server.connections(), 0u);
  }
  EXPECT_FALSE(std::filesystem::exists(path)) << "close() removes the socket file";
}

TEST(ControlServerTest, StaleUnixSocketIsReplacedLiveOneRefused) {
  TempDir dir;
  const std::string path = dir.file("control.sock");
  {  // a socket file nobody listens on, as a crashed service leaves it
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    std::memcpy(sa.sun_path, path.data(), path.size());
    ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&sa), sizeof sa), 0);
    ::close(fd);
  }
  ASSERT_TRUE(std::filesystem::is_socket(path));
  EXPECT_THROW(Client::unix_socket(path), std::runtime_error);

  Running live("unix:" + path);
  expect_echo(Client::unix_socket(path).request(echo(1)), 1);

  boost::asio::io_context io;
  TestHandler handler;
  try {
    ControlServer second(io, ListenAddress::parse("unix:" + path), handler, {});
    FAIL() << "a second server took over a live socket";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("another process is listening on " + path),
              std::string::npos)
        << e.what();
  }
  expect_echo(Client::unix_socket(path).request(echo(2)), 2);  // the first one is untouched

  const std::string plain = dir.file("notes.txt");
  std::ofstream(plain) << "keep me\n";
  try {
    ControlServer third(io, ListenAddress::parse("unix:" + plain), handler, {});
    FAIL() << "a regular file was replaced by a socket";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is not a socket"), std::string::npos) << e.what();
  }
  std::ifstream in(plain);
  std::string content;
  std::getline(in, content);
  EXPECT_EQ(content, "keep me");
}

}  // namespace
}  // namespace ncd::comms
