// The web dashboard of `ncd serve` (docs/web-dashboard.md) against a real service process: the
// page and its assets as in web/, the WebSocket's answers to bad messages (error replies, the
// service goes on), the token and loopback rules, TLS, and a real headless Chromium driven
// through chromedriver's W3C WebDriver protocol that submits, starts and holds a job from the
// page and shows what the control socket reports.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/core/detail/base64.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <set>
#include <thread>
#include <vector>

#include "tests/api/broker.hpp"
#include "tests/api/watcher.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/app/serve_fixture.hpp"
#include "tests/common/process.hpp"
#include "tests/web/webdriver.hpp"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using ncd::test::find_program;
using ncd::test::free_port;
using ncd::test::http_request;
using ncd::test::ServeFixture;
using ncd::test::slurp;
using ncd::test::WebDriver;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A WebSocket client of the dashboard with read time limits.
class WsClient {
 public:
  WsClient(std::uint16_t port, const std::string& origin = "") : ws_(io_) {
    ws_.next_layer().connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    if (!origin.empty()) {
      ws_.set_option(websocket::stream_base::decorator(
          [origin](websocket::request_type& r) { r.set(http::field::origin, origin); }));
    }
    ws_.read_message_max(64 << 20);
    ws_.handshake("127.0.0.1:" + std::to_string(port), "/ws");
  }
  // Sends one message; false when the server has closed the connection meanwhile.
  bool send(const std::string& text, bool binary = false) {
    ws_.binary(binary);
    beast::error_code ec;
    ws_.write(asio::buffer(text), ec);
    if (ec) closed_ = ec;
    return !ec;
  }
  // The next message within timeout_s; none after it (the read stays pending for the next
  // call: a cancelled read would end the WebSocket), or when the server closed.
  std::optional<json> next(double timeout_s = 20.0) {
    if (!reading_) {
      reading_ = true;
      result_.reset();
      ws_.async_read(buffer_, [this](const beast::error_code& ec, std::size_t) { result_ = ec; });
    }
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    io_.restart();
    while (!result_ && std::chrono::steady_clock::now() < end) {
      io_.run_one_for(std::chrono::duration_cast<std::chrono::nanoseconds>(
          end - std::chrono::steady_clock::now()));
    }
    if (!result_) return std::nullopt;
    reading_ = false;
    if (*result_) {
      closed_ = *result_;
      return std::nullopt;
    }
    json m = json::parse(beast::buffers_to_string(buffer_.data()));
    buffer_.consume(buffer_.size());
    if (m.contains("program")) last_program_ = m["program"];
    if (m.contains("event")) events.push_back(m["event"]);
    return m;
  }
  // The next message with `key` ("reply", "status", "program"), skipping others.
  json next_with(const std::string& key, double timeout_s = 20.0) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      const auto m = next(timeout_s);
      if (!m) break;
      if (m->contains(key)) return (*m)[key];
    }
    ADD_FAILURE() << "no message with \"" << key << "\"";
    return json::object();
  }
  json request(const json& req) {
    send(req.dump());
    return next_with("reply");
  }
  beast::error_code closed() const { return closed_; }
  // The programmed path sent for `job` (messages read meanwhile are skipped).
  json program_of(const std::string& job, double timeout_s = 20.0) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (last_program_.value("job", std::string()) != job &&
           std::chrono::steady_clock::now() < end) {
      next(0.1);
    }
    EXPECT_EQ(last_program_.value("job", std::string()), job);
    return last_program_;
  }

 private:
  asio::io_context io_;
  websocket::stream<tcp::socket> ws_;
  beast::error_code closed_;
  beast::flat_buffer buffer_;
  bool reading_ = false;
  std::optional<beast::error_code> result_;
  json last_program_ = json::object();

 public:
  std::vector<json> events;  // every {"event": …} read, in order (also those skipped)
};

// The control socket client (a Unix socket).
class SocketClient {
 public:
  explicit SocketClient(const std::string& path) {
    fd_ = socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    for (int i = 0; i < 400; ++i) {
      if (connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return;
      std::this_thread::sleep_for(25ms);
    }
    ADD_FAILURE() << "cannot connect to " << path;
  }
  ~SocketClient() { close(fd_); }
  json request(const json& req) {
    const std::string s = req.dump() + "\n";
    EXPECT_EQ(write(fd_, s.data(), s.size()), static_cast<ssize_t>(s.size()));
    for (;;) {
      const auto nl = buf_.find('\n');
      if (nl != std::string::npos) {
        const std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return json::parse(line);
      }
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 10000) <= 0) return json{{"ok", false}, {"error", "no reply"}};
      char tmp[4096];
      const ssize_t n = read(fd_, tmp, sizeof tmp);
      if (n <= 0) return json{{"ok", false}, {"error", "closed"}};
      buf_.append(tmp, static_cast<std::size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

// A slow program (5 mm/s over about 110 mm): a job that is still moving when the page holds it.
const char* kProgram =
    "G21 G90 G17\nG0 X0 Y0 Z5\nG1 Z0 F200\nG1 X30 Y0 F300\nG2 X30 Y20 I0 J10\nG1 X0 Y20\n"
    "G1 X0 Y0 Z-1\nM2\n";

class WebDashboard : public ServeFixture {
 protected:
  // Starts `ncd serve` with [http] on a kernel-chosen port; returns the dashboard's port (0 if
  // it did not come up within 30 s).
  std::uint16_t launch(const std::string& http, const std::string& extra = "",
                       const std::string& clock = "simulated") {
    ServeFixture::launch(clock, extra + "[http]\n" + http);
    err_ = dir_ / "serve.err";
    const std::regex re("dashboard on https?://[^:]+:([0-9]+)/");
    for (int i = 0; i < 3000; ++i) {
      std::smatch m;
      const std::string log = slurp(err_);
      if (std::regex_search(log, m, re)) {
        return static_cast<std::uint16_t>(std::stoi(m[1]));
      }
      std::this_thread::sleep_for(10ms);
    }
    ADD_FAILURE() << "the dashboard did not start: " << slurp(err_);
    return 0;
  }
  fs::path err_;
};

TEST_F(WebDashboard, ServesThePageOfTheRepository) {
  const std::uint16_t port = launch("listen = \"tcp:127.0.0.1:0\"\n");
  ASSERT_NE(port, 0);
  for (const char* name : {"index.html", "app.js", "style.css"}) {
    const auto [code, body] = http_request(port, http::verb::get, std::string("/") + name);
    EXPECT_EQ(code, 200) << name;
    EXPECT_EQ(body, slurp(fs::path(NCD_SOURCE_DIR) / "web" / name)) << name;  // embedded as is
  }
  EXPECT_EQ(http_request(port, http::verb::get, "/").second,
            slurp(fs::path(NCD_SOURCE_DIR) / "web" / "index.html"));
  EXPECT_EQ(http_request(port, http::verb::get, "/../serve.toml").first, 404);
  EXPECT_EQ(http_request(port, http::verb::get, "/nothing").first, 404);
  EXPECT_EQ(http_request(port, http::verb::post, "/", "{}").first, 405);
  EXPECT_EQ(terminate(), 0);
}

TEST_F(WebDashboard, AssetsFromAnInstalledDirectory) {
  fs::create_directories(dir_ / "assets");
  std::ofstream(dir_ / "assets" / "index.html") << "<p>installed</p>";
  const std::uint16_t port =
      launch("listen = \"tcp:127.0.0.1:0\"\nassets = \"" + (dir_ / "assets").string() + "\"\n");
  ASSERT_NE(port, 0);
  EXPECT_EQ(http_request(port, http::verb::get, "/").second, "<p>installed</p>");
  const auto [code, body] = http_request(port, http::verb::get, "/app.js");
  EXPECT_EQ(code, 500);  // named as missing, not served from elsewhere
  EXPECT_NE(body.find("app.js"), std::string::npos) << body;
}

TEST_F(WebDashboard, WebSocketAnswersBadMessagesAndGoesOn) {
  const std::uint16_t port = launch("listen = \"tcp:127.0.0.1:0\"\n");
  ASSERT_NE(port, 0);
  WsClient ws(port);
  const std::vector<std::string> bad = {
      "{not json",
      "[1,2]",
      "{\"cmd\":3}",
      "{\"cmd\":\"fly\"}",
      "{\"cmd\":\"override\",\"percent\":\"fast\"}",
      "{\"cmd\":\"subscribe\",\"hz\":1e9}",
      "{\"cmd\":\"upload\",\"name\":\"part.ngc\"}",
      "{\"cmd\":\"upload\",\"name\":\"../../noextension\",\"text\":\"G0 X1\"}",
      "{\"cmd\":\"upload\",\"name\":\"part.ngc\",\"text\":\"G1 X10 F-5\\n\"}",
      "{\"cmd\":\"upload\",\"name\":\"part.json\",\"text\":\"{\\\"nurbs\\\": 3}\"}",
      "{\"cmd\":\"upload\",\"name\":\"p.ngc\",\"text\":\"G0 X1\",\"colour\":1}",
      "{\"cmd\":\"start\"}",
      "{\"cmd\":\"hold\"}",
      std::string(100, '{')};
  for (const std::string& m : bad) {
    ws.send(m);
    const json r = ws.next_with("reply");
    EXPECT_EQ(r.value("ok", true), false) << m << " → " << r.dump();
    EXPECT_FALSE(r.value("error", std::string()).empty()) << m;
  }
  ws.send("\x01\x02", true);  // a binary frame
  EXPECT_EQ(ws.next_with("reply").value("ok", true), false);
  // The same checks as the socket: the socket's reply to the same bad request.
  SocketClient sock(socket_);
  EXPECT_EQ(ws.request({{"cmd", "fly"}})["error"], sock.request({{"cmd", "fly"}})["error"]);
  // Status flows at the configured rate and agrees with the socket.
  const json st = ws.next_with("status");
  EXPECT_EQ(st["state"], sock.request({{"cmd", "status"}})["state"]);
  // A message over the limit closes that WebSocket (1009), not the service.
  ws.send(std::string(9u << 20, ' '));
  for (int i = 0; i < 100 && ws.next(5.0); ++i) {
  }
  EXPECT_TRUE(ws.closed()) << "the oversized message did not close the WebSocket";
  WsClient again(port);
  EXPECT_TRUE(again.request({{"cmd", "status"}}).value("ok", false));
  EXPECT_TRUE(sock.request({{"cmd", "status"}}).value("ok", false));
  EXPECT_EQ(terminate(), 0);
}

TEST_F(WebDashboard, UploadSubmitsAndSendsTheProgrammedPath) {
  const std::uint16_t port = launch("listen = \"tcp:127.0.0.1:0\"\nstatus_hz = 20\n");
  ASSERT_NE(port, 0);
  WsClient ws(port);
  const json r = ws.request({{"cmd", "upload"}, {"name", "slow part.ngc"}, {"text", kProgram}});
  ASSERT_TRUE(r.value("ok", false)) << r.dump();
  EXPECT_EQ(r["state"], "ready");
  EXPECT_EQ(slurp(r["job"].get<std::string>()), kProgram);  // the upload, byte for byte
  // A second upload replaces the first's file; a refused one leaves none.
  const json r2 = ws.request({{"cmd", "upload"}, {"name", "again.ngc"}, {"text", kProgram}});
  ASSERT_TRUE(r2.value("ok", false)) << r2.dump();
  EXPECT_FALSE(fs::exists(r["job"].get<std::string>()));
  EXPECT_TRUE(fs::exists(r2["job"].get<std::string>()));
  const json bad = ws.request({{"cmd", "upload"}, {"name", "bad.ngc"}, {"text", "G1 X1 F-5\n"}});
  EXPECT_FALSE(bad.value("ok", true));
  EXPECT_EQ(
      std::distance(fs::directory_iterator(fs::path(r2["job"].get<std::string>()).parent_path()),
                    fs::directory_iterator()),
      1);
  const json program = ws.program_of(r2["job"].get<std::string>());
  EXPECT_EQ(program["programmed_feed_max_mm_per_min"], 300.0);
  // The preview passes through the program's corners (a closed form: the G-code's own points).
  const auto has = [&](double x, double y, double z) {
    for (const auto& p : program["points"]) {
      if (std::abs(p[0].get<double>() - x) < 1e-9 && std::abs(p[1].get<double>() - y) < 1e-9 &&
          std::abs(p[2].get<double>() - z) < 1e-9) {
        return true;
      }
    }
    return false;
  };
  EXPECT_TRUE(has(30, 0, 0));
  EXPECT_TRUE(has(30, 20, 0));
  EXPECT_TRUE(has(0, 0, -1));
  // The G2 arc from (30, 0) to (30, 20) about (30, 10) runs clockwise, through x = 20: its
  // samples (the points strictly between the two straight cuts) stay on its circle.
  int on_arc = 0;
  for (const auto& p : program["points"]) {
    const double x = p[0].get<double>(), y = p[1].get<double>();
    if (x > 1e-9 && y > 1e-9 && y < 20 - 1e-9) {
      EXPECT_NEAR(std::hypot(x - 30, y - 10), 10.0, 1e-6) << p.dump();
      EXPECT_LE(x, 30 + 1e-9) << p.dump();
      ++on_arc;
    }
  }
  EXPECT_GE(on_arc, 10);
  // The job runs to its end like a socket job (simulated clock).
  ASSERT_TRUE(ws.request({{"cmd", "start"}}).value("ok", false));
  SocketClient sock(socket_);
  json s;
  for (int i = 0; i < 2000; ++i) {
    s = sock.request({{"cmd", "status"}});
    if (s["state"] == "done") break;
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_EQ(s["state"], "done") << s.dump();
  EXPECT_NEAR(s["position"][0].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(s["position"][2].get<double>(), -1.0, 1e-9);
}

// The service's events reach an open page as {"event": …}, in the service's order with no gap,
// the hold as a state event held by the operator; a page opened later gets the last ones.
TEST_F(WebDashboard, TheServicesEventsReachThePage) {
  const std::uint16_t port = launch("listen = \"tcp:127.0.0.1:0\"\nstatus_hz = 20\n", "", "wall");
  ASSERT_NE(port, 0);
  WsClient ws(port);
  ASSERT_TRUE(
      ws.request({{"cmd", "upload"}, {"name", "slow.ngc"}, {"text", kProgram}}).value("ok", false));
  ASSERT_TRUE(ws.request({{"cmd", "start"}}).value("ok", false));
  const auto seen = [&](const std::string& kind, const std::string& state) {
    for (int i = 0; i < 400; ++i) {
      for (const json& e : ws.events) {
        if (e["kind"] == kind && e["state"] == state) return true;
      }
      ws.next(0.05);
    }
    return false;
  };
  ASSERT_TRUE(seen("job", "running"));
  ASSERT_TRUE(ws.request({{"cmd", "hold"}}).value("ok", false));
  ASSERT_TRUE(seen("state", "holding"));
  const std::vector<json> events = ws.events;
  EXPECT_EQ(events.front()["service_seq"], 1);
  for (std::size_t i = 1; i < events.size(); ++i) {
    EXPECT_EQ(events[i]["service_seq"].get<std::uint64_t>(),
              events[i - 1]["service_seq"].get<std::uint64_t>() + 1)
        << events[i].dump();
  }
  std::vector<std::string> lifecycle;  // kind:state:holder of the state and job events
  for (const json& e : events) {
    if (e["kind"] == "state" || e["kind"] == "job") {
      lifecycle.push_back(e["kind"].get<std::string>() + ":" + e["state"].get<std::string>() + ":" +
                          e["holder"].get<std::string>());
    }
  }
  const std::vector<std::string> want = {"state:ready:none", "job:ready:none", "state:running:none",
                                         "job:running:none", "state:holding:operator"};
  EXPECT_EQ(lifecycle, want);
  EXPECT_EQ(events.back()["text"], "held by the operator");
  // A page opened now gets the recent events, the hold among them.
  WsClient late(port);
  bool saw_hold = false;
  for (int i = 0; i < 100 && !saw_hold; ++i) {
    late.next(0.05);
    for (const json& e : late.events) {
      saw_hold = saw_hold || (e["state"] == "holding" && e["holder"] == "operator");
    }
  }
  EXPECT_TRUE(saw_hold);
  EXPECT_TRUE(ws.request({{"cmd", "stop"}}).value("ok", false));
}

TEST_F(WebDashboard, TokenAndLoopbackRules) {
  // Not loopback and no token: refused, naming the value and the way out.
  const std::string open = write("open.toml", "[http]\nlisten = \"tcp:0.0.0.0:0\"\n");
  auto r = ncd("serve --config " + open + " --listen unix:" + (dir_ / "a.sock").string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("tcp:0.0.0.0:0"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("token"), std::string::npos) << r.err;
  // Bad [http] keys: exit 2 with the key named.
  for (const auto& [text, word] : std::vector<std::pair<std::string, std::string>>{
           {"[http]\nlisten = \"unix:/tmp/x\"\n", "TCP only"},
           {"[http]\nlisten = \"tcp:127.0.0.1:0\"\ncertificate = \"c.pem\"\n", "both"},
           {"[http]\nlisten = \"tcp:127.0.0.1:0\"\nstatus_hz = 500\n", "at most 50"},
           {"[http]\nlisten = \"tcp:127.0.0.1:0\"\nport = 80\n", "unknown key"},
           {"[http]\nlisten = \"tcp:127.0.0.1:0\"\ncertificate = \"/nonexistent.pem\"\nkey = "
            "\"/nonexistent.key\"\n",
            "/nonexistent.pem"},
           {"http = 3\n", "table"}}) {
    r = ncd("serve --config " + write("bad.toml", text) +
            " --listen unix:" + (dir_ / "b.sock").string());
    EXPECT_EQ(r.status, 2) << text;
    EXPECT_NE(r.err.find(word), std::string::npos) << text << " → " << r.err;
  }
  // Not loopback with a token: it serves; no status and no command without the token.
  const std::uint16_t port = launch("listen = \"tcp:0.0.0.0:0\"\n", "token = \"s3cret\"\n");
  ASSERT_NE(port, 0);
  WsClient ws(port);
  const json no = ws.request({{"cmd", "status"}});
  EXPECT_FALSE(no.value("ok", true));
  EXPECT_NE(no.value("error", std::string()).find("token"), std::string::npos) << no.dump();
  EXPECT_FALSE(ws.request({{"cmd", "hold"}, {"token", "wrong"}}).value("ok", true));
  for (int i = 0; i < 3; ++i) {  // 0.6 s: at 10 Hz, six snapshots would have come
    const auto m = ws.next(0.2);
    EXPECT_FALSE(m && m->contains("status")) << "status without the token: " << m->dump();
  }
  EXPECT_TRUE(ws.request({{"cmd", "status"}, {"token", "s3cret"}}).value("ok", false));
  EXPECT_EQ(ws.next_with("status")["state"], "idle");
  // A page from another site cannot open the WebSocket (403).
  EXPECT_EQ(http_request(port, http::verb::get, "/", "", "http://evil.example").first, 200);
  try {
    WsClient foreign(port, "http://evil.example");
    ADD_FAILURE() << "a WebSocket from another origin was accepted";
  } catch (const beast::system_error& e) {
    EXPECT_EQ(e.code(), websocket::error::upgrade_declined) << e.what();
  }
  WsClient same(port, "http://127.0.0.1:" + std::to_string(port));
  EXPECT_TRUE(same.request({{"cmd", "status"}, {"token", "s3cret"}}).value("ok", false));
}

TEST_F(WebDashboard, TlsWhenCertificateAndKeyAreGiven) {
  const std::string openssl = find_program({"openssl"});
  const std::string curl = find_program({"curl"});
  if (openssl.empty() || curl.empty()) GTEST_SKIP() << "needs openssl and curl on PATH";
  const std::string cert = (dir_ / "cert.pem").string(), key = (dir_ / "key.pem").string();
  ASSERT_EQ(std::system((openssl + " req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=ncd " +
                         "-keyout " + key + " -out " + cert + " >/dev/null 2>&1")
                            .c_str()),
            0);
  const std::uint16_t port = launch("listen = \"tcp:127.0.0.1:0\"\ncertificate = \"" + cert +
                                    "\"\nkey = \"" + key + "\"\n");
  ASSERT_NE(port, 0);
  EXPECT_NE(slurp(err_).find("dashboard on https://"), std::string::npos);
  const std::string out = (dir_ / "page.html").string();
  ASSERT_EQ(std::system((curl + " -s --cacert " + cert + " -o " + out +
                         " https://127.0.0.1:" + std::to_string(port) +
                         "/ --resolve ncd:" + std::to_string(port) + ":127.0.0.1 -k")
                            .c_str()),
            0);
  EXPECT_EQ(slurp(out), slurp(fs::path(NCD_SOURCE_DIR) / "web" / "index.html"));
  // The WebSocket over TLS (wss), the certificate checked against the one generated here.
  {
    asio::io_context io;
    asio::ssl::context tls(asio::ssl::context::tls_client);
    tls.load_verify_file(cert);
    tls.set_verify_mode(asio::ssl::verify_peer);
    websocket::stream<beast::ssl_stream<tcp::socket>> wss(io, tls);
    beast::get_lowest_layer(wss).connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    wss.next_layer().handshake(asio::ssl::stream_base::client);
    wss.handshake("127.0.0.1:" + std::to_string(port), "/ws");
    wss.text(true);
    wss.write(asio::buffer(json{{"cmd", "status"}}.dump()));
    bool replied = false, status = false;
    for (int i = 0; i < 10 && !(replied && status); ++i) {
      beast::flat_buffer buffer;
      wss.read(buffer);
      const json m = json::parse(beast::buffers_to_string(buffer.data()));
      replied = replied || (m.contains("reply") && m["reply"]["state"] == "idle");
      status = status || (m.contains("status") && m["status"]["state"] == "idle");
    }
    EXPECT_TRUE(replied && status);
  }
  // Plain HTTP on the TLS port gets no page.
  const int plain = std::system(
      (curl + " -s -m 5 -o /dev/null http://127.0.0.1:" + std::to_string(port) + "/").c_str());
  EXPECT_NE(plain, 0);
}

TEST_F(WebDashboard, BrowserSubmitsStartsAndHoldsAJob) {
  const std::string chromium = find_program({"chromium", "chromium-browser", "google-chrome"});
  const std::string driver = find_program({"chromedriver"});
  if (chromium.empty() || driver.empty()) {
    GTEST_SKIP() << "headless browser test skipped: chromium and chromedriver are not on PATH "
                    "(apt-get install chromium chromium-driver)";
  }
  const std::uint16_t port = launch("listen = \"tcp:127.0.0.1:0\"\nstatus_hz = 20\n", "", "wall");
  ASSERT_NE(port, 0);
  const std::string program = write("slow.ngc", kProgram);
  const std::uint16_t driver_port = free_port();
  ncd::test::Process chromedriver({driver, "--port=" + std::to_string(driver_port)},
                                  (dir_ / "driver.out").string(), (dir_ / "driver.err").string());
  WebDriver page(driver_port, chromium, (dir_ / "profile").string());
  page.go("http://127.0.0.1:" + std::to_string(port) + "/");
  ASSERT_TRUE(page.wait_text("conn", "connected")) << page.text("conn");
  ASSERT_TRUE(page.wait_text("state", "idle")) << page.text("state");
  // Submit the program from the page (a real file upload), then start it with cycle start.
  page.type("#program-file", program);
  page.click("#submit-file");
  ASSERT_TRUE(page.wait_text("state", "ready")) << page.text("message");
  SocketClient sock(socket_);
  json s = sock.request({{"cmd", "status"}});
  EXPECT_EQ(s["state"], "ready");
  EXPECT_EQ(page.text("job"), s["job"].get<std::string>());
  EXPECT_NE(s["job"].get<std::string>().find("slow.ngc"), std::string::npos) << s.dump();
  page.click("#cycle-start");
  ASSERT_TRUE(page.wait_text("state", "running")) << page.text("message");
  // Let it move a while (past the plunge, into the first cut), then hold from the page.
  for (int i = 0; i < 400; ++i) {
    s = sock.request({{"cmd", "status"}});
    if (s["position"][0].get<double>() > 12.0) break;
    std::this_thread::sleep_for(50ms);
  }
  page.click("#hold");
  ASSERT_TRUE(page.wait_text("state", "holding")) << page.text("message");
  EXPECT_EQ(sock.request({{"cmd", "status"}})["state"], "holding");
  // The page lists the service's events, the newest first: the hold, by the operator.
  for (int i = 0;
       i < 100 && page.text("events").find("holding by the operator") == std::string::npos; ++i) {
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_NE(page.text("events").find("holding by the operator · held by the operator"),
            std::string::npos)
      << page.text("events");
  // At rest (the hold's jerk-limited stop), the page shows the socket's position to 0.001 mm.
  for (int i = 0; i < 200; ++i) {
    s = sock.request({{"cmd", "status"}});
    if (s["feed_mm_per_min"].get<double>() == 0.0) break;
    std::this_thread::sleep_for(50ms);
  }
  ASSERT_EQ(s["feed_mm_per_min"].get<double>(), 0.0);
  std::this_thread::sleep_for(300ms);  // a few snapshots at 20 Hz
  s = sock.request({{"cmd", "status"}});
  const char* ids[] = {"pos-x", "pos-y", "pos-z"};
  for (int k = 0; k < 3; ++k) {
    const std::string shown = page.text(ids[k]);
    ASSERT_FALSE(shown.empty() || shown == "-") << ids[k];
    EXPECT_NEAR(std::stod(shown), s["position"][k].get<double>(), 0.0005 + 1e-12) << ids[k];
  }
  EXPECT_GT(s["position"][0].get<double>(), 12.0);
  // Past x = 12 on y = 0 the tool is on "G1 X30 Y0 F300", line 4 of kProgram (its own segment:
  // its feed differs from line 3's); at rest under the hold, the hold binds the feed.
  EXPECT_NEAR(s["position"][1].get<double>(), 0.0, 1e-9);
  EXPECT_EQ(s["line"], 4) << s.dump();
  EXPECT_EQ(page.text("line"), "4");
  EXPECT_EQ(s["binding_limit"], "hold") << s.dump();
  EXPECT_NE(page.text("feed-limit-note").find("binding: hold"), std::string::npos)
      << page.text("feed-limit-note");
  // The feed's ceiling shown: the status's limit (the F word 300 here, at rest under the hold)
  // times the override, to the page's 0.1 mm/min.
  ASSERT_TRUE(s["feed_limit_mm_per_min"].is_number()) << s.dump();
  EXPECT_NEAR(std::stod(page.text("feed-limit")), s["feed_limit_mm_per_min"].get<double>(),
              0.05 + 1e-9);
  EXPECT_EQ(page.text("feed"), "0.0");
  EXPECT_EQ(page.text("override"), "100");
  // The page drew the programmed path and the tool's trace.
  EXPECT_GT(page.script("return program.points.length;").get<int>(), 10);
  EXPECT_GT(page.script("return trace.length;").get<int>(), 10);
  const std::string png = page.screenshot_png();
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  // The screenshot lands in the test's working folder (the build tree); the README's copy in
  // docs/img is refreshed only on request: NCD_UPDATE_SCREENSHOT=1. A test run never edits the
  // source tree.
  const char* update = std::getenv("NCD_UPDATE_SCREENSHOT");
  const fs::path shot = update != nullptr && std::string(update) == "1"
                            ? fs::path(NCD_SOURCE_DIR) / "docs" / "img" / "dashboard.png"
                            : fs::current_path() / "dashboard.png";
  std::ofstream(shot, std::ios::binary) << png;
  std::cout << "screenshot: " << shot << " (" << png.size() << " bytes)\n";
  // Cycle start resumes a held job; stop ends it on the path.
  page.click("#cycle-start");
  ASSERT_TRUE(page.wait_text("state", "running")) << page.text("message");
  page.click("#stop");
  ASSERT_TRUE(page.wait_text("state", "stopped")) << page.text("message");
  EXPECT_EQ(sock.request({{"cmd", "status"}})["state"], "stopped");
  // `page` goes first: its session's DELETE quits the browser, then chromedriver is killed.
}

// The link panel against the socket: a job streamed live (drip, iso) to `ncd sim-controller`
// on a pseudo-terminal, both on the wall clock, held from the page once some blocks have gone.
// Under the hold the sender runs dry and its counters stand still; the page then shows the
// socket's bytes written, blocks written and underruns, and the feed ceiling the socket gives.
TEST_F(WebDashboard, BrowserLinkPanelShowsTheSocketsLiveCounters) {
  const std::string chromium = find_program({"chromium", "chromium-browser", "google-chrome"});
  const std::string driver = find_program({"chromedriver"});
  if (chromium.empty() || driver.empty()) {
    GTEST_SKIP() << "headless browser test skipped: chromium and chromedriver are not on PATH "
                    "(apt-get install chromium chromium-driver)";
  }
  const std::string port_path = (dir_ / "cnc").string();
  ncd::test::Process controller({NCD_EXE, "sim-controller", "--link", port_path, "--baud", "115200",
                                 "--frame", "8N1", "--flow", "xonxoff", "--protocol", "drip",
                                 "--eob", "lf", "--dialect", "iso", "--no-machine-safety"},
                                (dir_ / "controller.out").string(),
                                (dir_ / "controller.err").string());
  ASSERT_TRUE(ncd::test::wait_for_path(port_path, 10.0)) << slurp(dir_ / "controller.err");
  const std::string machine = write(
      "machine.toml",
      "period_s = 0.004\nmax_feed_mm_per_min = 6000.0\n\n[link]\ndevice = \"" + port_path +
          "\"\nbaud = 115200\nframe = \"8N1\"\nflow = \"xonxoff\"\nprotocol = \"drip\"\n"
          "eob = \"lf\"\npercent = true\ndialect = \"iso\"\n\n[encoder]\nmax_block_s = 0.5\n");
  const std::uint16_t port = launch("listen = \"tcp:127.0.0.1:0\"\nstatus_hz = 20\n",
                                    "machine = \"" + machine + "\"\n", "wall");
  ASSERT_NE(port, 0);
  const std::string program = write("slow.ngc", kProgram);
  const std::uint16_t driver_port = free_port();
  ncd::test::Process chromedriver({driver, "--port=" + std::to_string(driver_port)},
                                  (dir_ / "driver.out").string(), (dir_ / "driver.err").string());
  WebDriver page(driver_port, chromium, (dir_ / "profile").string());
  page.go("http://127.0.0.1:" + std::to_string(port) + "/");
  ASSERT_TRUE(page.wait_text("conn", "connected")) << page.text("conn");
  page.type("#program-file", program);
  page.click("#submit-file");
  ASSERT_TRUE(page.wait_text("state", "ready")) << page.text("message");
  page.click("#cycle-start");
  ASSERT_TRUE(page.wait_text("state", "running")) << page.text("message") << slurp(err_);
  SocketClient sock(socket_);
  json s;
  for (int i = 0; i < 400; ++i) {
    s = sock.request({{"cmd", "status"}});
    if (s["stream"].is_object() && s["stream"]["blocks_written"].get<int>() >= 3) break;
    std::this_thread::sleep_for(50ms);
  }
  ASSERT_TRUE(s["stream"].is_object() && s["stream"]["blocks_written"].get<int>() >= 3)
      << s.dump() << slurp(err_);
  page.click("#hold");
  ASSERT_TRUE(page.wait_text("state", "holding")) << page.text("message");
  // The motion at rest, the encoder's last block sent: the counters stand still.
  json k;
  for (int i = 0; i < 100; ++i) {
    const json before = sock.request({{"cmd", "status"}})["stream"];
    std::this_thread::sleep_for(300ms);
    s = sock.request({{"cmd", "status"}});
    k = s["stream"];
    if (k == before && s["feed_mm_per_min"].get<double>() == 0.0) break;
  }
  ASSERT_EQ(s["state"], "holding") << s.dump();
  EXPECT_FALSE(k["done"].get<bool>()) << k.dump();
  EXPECT_GT(k["bytes_written"].get<std::int64_t>(), 0) << k.dump();
  // The page, at 20 status snapshots a second, shows the same numbers.
  EXPECT_TRUE(
      page.wait_text("link-bytes", std::to_string(k["bytes_written"].get<std::int64_t>()), 10.0))
      << page.text("link-bytes") << " against " << k.dump();
  EXPECT_EQ(page.text("link-written"), std::to_string(k["blocks_written"].get<std::int64_t>()));
  EXPECT_EQ(page.text("link-underruns"), std::to_string(k["underruns"].get<std::int64_t>()));
  EXPECT_EQ(page.text("link-acked"), "-");  // drip: nothing is acknowledged
  EXPECT_NE(page.text("link-buffer").find("wire model"), std::string::npos)
      << page.text("link-buffer");
  std::cout << "[ measured ] link under the hold: " << k.dump() << "\n";
  // Drip feed reports nothing of the controller: the DRO is ncd's commanded position, so
  // labelled, and the controller's place is the last block the line carried; at rest, with
  // the buffer empty, every block written has been carried.
  EXPECT_TRUE(s["controller"].is_null()) << s.dump();
  const json q = s["controller_progress"];
  ASSERT_TRUE(q.is_object()) << s.dump();
  EXPECT_EQ(q["source"], "last sent") << q.dump();
  if (k["controller_buffer_bytes"] == 0) {
    EXPECT_EQ(q["blocks_behind"].get<std::int64_t>(),
              k["blocks_encoded"].get<std::int64_t>() - k["blocks_written"].get<std::int64_t>())
        << q.dump() << k.dump();
  }
  EXPECT_TRUE(page.wait_text("dro-source", "commanded by ncd (ahead of the controller)"))
      << page.text("dro-source");
  EXPECT_NE(
      page.text("behind").find(std::to_string(q["blocks_behind"].get<std::int64_t>()) + " blocks"),
      std::string::npos)
      << page.text("behind");
  EXPECT_EQ(page.text("ctl-state"), "not reported (drip feed)");
  page.click("#stop");
  ASSERT_TRUE(page.wait_text("state", "stopped", 60.0)) << page.text("message") << slurp(err_);
}

// A page of a wall-clock `ncd serve` in headless Chromium (dashboard tests of issue 33): the
// service, chromedriver and the page, or a skip when no browser is installed.
class BrowserPage : public WebDashboard {
 protected:
  void SetUp() override {
    WebDashboard::SetUp();
    chromium_ = find_program({"chromium", "chromium-browser", "google-chrome"});
    driver_ = find_program({"chromedriver"});
    if (chromium_.empty() || driver_.empty()) {
      GTEST_SKIP() << "headless browser test skipped: chromium and chromedriver are not on PATH "
                      "(apt-get install chromium chromium-driver)";
    }
  }
  // Starts the service (wall clock, 20 status snapshots a second) and opens its page.
  WebDriver& open(const std::string& extra = "") {
    start_service(extra);
    return open_page();
  }
  void start_service(const std::string& extra = "") {
    port_ = launch("listen = \"tcp:127.0.0.1:0\"\nstatus_hz = 20\n", extra, "wall");
    if (port_ == 0) throw std::runtime_error("the dashboard did not start");
  }
  WebDriver& open_page() {
    const std::uint16_t driver_port = free_port();
    chromedriver_.emplace(
        std::vector<std::string>{driver_, "--port=" + std::to_string(driver_port)},
        (dir_ / "driver.out").string(), (dir_ / "driver.err").string());
    page_.emplace(driver_port, chromium_, (dir_ / "profile").string());
    page_->go("http://127.0.0.1:" + std::to_string(port_) + "/");
    EXPECT_TRUE(page_->wait_text("conn", "connected")) << page_->text("conn");
    return *page_;
  }
  void TearDown() override {
    page_.reset();  // its session's DELETE quits the browser, then chromedriver is killed
    chromedriver_.reset();
    WebDashboard::TearDown();
  }
  // Waits up to timeout_s for `pred` on the page's element `id` (its text).
  bool wait_for(const std::string& id, const std::function<bool(const std::string&)>& pred,
                double timeout_s = 30.0) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      if (pred(page_->text(id))) return true;
      std::this_thread::sleep_for(50ms);
    }
    return false;
  }
  std::string chromium_, driver_;
  std::uint16_t port_ = 0;
  std::optional<ncd::test::Process> chromedriver_;
  std::optional<WebDriver> page_;
};

double dashboard_unix_now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// HH:MM:SS of a Unix time in the local time zone (the browser's: the same TZ as this process).
std::string clock_text(double unix_s) {
  const std::time_t t = static_cast<std::time_t>(std::floor(unix_s));
  std::tm tm{};
  localtime_r(&t, &tm);
  char out[16];
  std::strftime(out, sizeof out, "%H:%M:%S", &tm);
  return out;
}

// Issue 33, "Event times all read 0.000 s": events during a job carry the motion time of the
// last setpoint (the hold's lies between the socket's t_s read just before and just after it),
// every event the wall clock (between the test's clock before and after), and the page lists
// both as "HH:MM:SS · t s"; the events before the first period (submitted) show the clock only.
TEST_F(BrowserPage, EventsShowTheirWallClockAndMotionTimes) {
  WebDriver& page = open();
  WsClient ws(port_);  // an independent reader of the same events
  const std::string program = write("slow.ngc", kProgram);
  const double submit_unix_s = dashboard_unix_now_s();
  page.type("#program-file", program);
  page.click("#submit-file");
  ASSERT_TRUE(page.wait_text("state", "ready")) << page.text("message");
  page.click("#cycle-start");
  ASSERT_TRUE(page.wait_text("state", "running")) << page.text("message");
  SocketClient sock(socket_);
  json s;
  for (int i = 0; i < 400; ++i) {
    s = sock.request({{"cmd", "status"}});
    if (s["position"][0].get<double>() > 5.0) break;
    std::this_thread::sleep_for(50ms);
  }
  const double t_before_s = sock.request({{"cmd", "status"}})["t_s"].get<double>();
  const double hold_unix_s = dashboard_unix_now_s();
  page.click("#hold");
  ASSERT_TRUE(page.wait_text("state", "holding")) << page.text("message");
  const double t_after_s = sock.request({{"cmd", "status"}})["t_s"].get<double>();
  const double after_unix_s = dashboard_unix_now_s();
  json hold;
  for (int i = 0; i < 200 && hold.is_null(); ++i) {
    ws.next(0.1);
    for (const json& e : ws.events) {
      if (e["kind"] == "state" && e["state"] == "holding") hold = e;
    }
  }
  ASSERT_FALSE(hold.is_null()) << json(ws.events).dump(1);
  const double hold_t_s = hold["job_t_s"].get<double>();
  EXPECT_GT(hold_t_s, 0.5) << hold.dump();               // 5 mm at 5 mm/s and the plunge before
  EXPECT_GE(hold_t_s, t_before_s - 0.1) << hold.dump();  // a poll's drain behind the cycle
  EXPECT_LE(hold_t_s, t_after_s) << hold.dump();
  EXPECT_GE(hold["time_unix_s"].get<double>(), hold_unix_s - 1e-3) << hold.dump();
  EXPECT_LE(hold["time_unix_s"].get<double>(), after_unix_s + 1e-3) << hold.dump();
  char want[64];
  std::snprintf(want, sizeof want, "%s · %.3f s · state · holding by the operator",
                clock_text(hold["time_unix_s"].get<double>()).c_str(), hold_t_s);
  EXPECT_TRUE(wait_for("events", [&](const std::string& t) { return t.find(want) == 0; }))
      << "want " << want << " first in: " << page.text("events");
  // The submit: the clock only (no motion yet), within the test's clock.
  const json first = page.script(
      "return Array.from(document.querySelectorAll('#events li')).map((li) => li.textContent);");
  ASSERT_TRUE(first.is_array() && !first.empty());
  const std::string submitted = first.back().get<std::string>();
  EXPECT_NE(submitted.find(" · state · ready · submitted"), std::string::npos) << submitted;
  EXPECT_EQ(submitted.find(" s · "), std::string::npos) << submitted;  // no motion time
  const std::string hhmmss = submitted.substr(0, 8);
  EXPECT_TRUE(hhmmss >= clock_text(submit_unix_s) && hhmmss <= clock_text(after_unix_s))
      << submitted;
  page.click("#stop");
  ASSERT_TRUE(page.wait_text("state", "stopped")) << page.text("message");
}

// The enabled controls of the page, as "id=0|1 …" in a fixed order.
std::string enabled_controls(WebDriver& page) {
  return page
      .script(
          "return ['cycle-start','start','hold','resume','stop','override-set','submit-file',"
          "'submit-chamfer'].map((id) => id + '=' + (document.getElementById(id).disabled ? 0 : "
          "1)).join(' ');")
      .get<std::string>();
}

// Issue 33: "Every button is enabled in every state" and "the page shows override 150 % while
// its slider shows 100". In each state the page enables only what the service takes, and the
// slider follows the service's override: on load (a preset set over the socket before the page
// opened), and while the job runs (set over the socket, not from the page).
TEST_F(BrowserPage, ControlsFollowTheStateAndTheSliderTheServicesOverride) {
  start_service();
  // The preset goes in over the socket before the page exists.
  SocketClient sock(socket_);
  ASSERT_TRUE(sock.request({{"cmd", "override"}, {"percent", 150}}).value("ok", false));
  WebDriver& page = open_page();
  const auto slider = [&] {
    return page.script("return document.getElementById('override-input').value;")
        .get<std::string>();
  };
  const auto wait_enabled = [&](const std::string& want) {
    for (int i = 0; i < 600 && enabled_controls(page) != want; ++i) {
      std::this_thread::sleep_for(50ms);
    }
    return enabled_controls(page);
  };
  ASSERT_TRUE(page.wait_text("state", "idle"));
  EXPECT_TRUE(page.wait_text("override", "150"));
  EXPECT_TRUE(page.wait_text("override-value", "150"));
  EXPECT_EQ(slider(), "150");
  EXPECT_EQ(wait_enabled("cycle-start=0 start=0 hold=0 resume=0 stop=0 override-set=1 "
                         "submit-file=1 submit-chamfer=1"),
            "cycle-start=0 start=0 hold=0 resume=0 stop=0 override-set=1 submit-file=1 "
            "submit-chamfer=1");
  page.type("#program-file", write("slow.ngc", kProgram));
  page.click("#submit-file");
  ASSERT_TRUE(page.wait_text("state", "ready")) << page.text("message");
  const std::string ready =
      "cycle-start=1 start=1 hold=0 resume=0 stop=0 override-set=1 submit-file=1 "
      "submit-chamfer=1";
  EXPECT_EQ(wait_enabled(ready), ready);
  page.click("#cycle-start");
  ASSERT_TRUE(page.wait_text("state", "running")) << page.text("message");
  const std::string running =
      "cycle-start=0 start=0 hold=1 resume=0 stop=1 override-set=1 submit-file=0 "
      "submit-chamfer=0";
  EXPECT_EQ(wait_enabled(running), running);
  // The preset was the job's: the socket and the page say 150.
  EXPECT_EQ(sock.request({{"cmd", "status"}})["override_percent"], 150.0);
  EXPECT_EQ(slider(), "150");
  // An override set elsewhere (the socket) moves the page's slider.
  ASSERT_TRUE(sock.request({{"cmd", "override"}, {"percent", 70}}).value("ok", false));
  EXPECT_TRUE(page.wait_text("override-value", "70")) << page.text("override-value");
  EXPECT_EQ(slider(), "70");
  page.click("#hold");
  ASSERT_TRUE(page.wait_text("state", "holding")) << page.text("message");
  const std::string holding =
      "cycle-start=1 start=0 hold=0 resume=1 stop=1 override-set=1 submit-file=0 "
      "submit-chamfer=0";
  EXPECT_EQ(wait_enabled(holding), holding);
  page.click("#stop");
  ASSERT_TRUE(page.wait_text("state", "stopped")) << page.text("message");
  const std::string stopped =
      "cycle-start=0 start=0 hold=0 resume=0 stop=0 override-set=1 submit-file=1 "
      "submit-chamfer=1";
  EXPECT_EQ(wait_enabled(stopped), stopped);
  // After the job the slider shows the next start's override: 100 (the preset was used).
  EXPECT_TRUE(page.wait_text("override-value", "100")) << page.text("override-value");
  EXPECT_EQ(slider(), "100");
}

// Issue 33: "The chamfer form lacks edge, side, tilt and eccentricity". The form sends them
// under the chamfer job's request keys (api/intake.cpp, `ncd chamfer`'s names), with the
// defaults of `ncd chamfer` when untouched; the service takes them (a tilt out of its range is
// refused by the service naming the key's value, so the key reached it).
TEST_F(BrowserPage, ChamferFormSendsEdgeSideTiltAndEccentricity) {
  WebDriver& page = open();
  ASSERT_TRUE(page.wait_text("state", "idle"));
  page.script(
      "window.sentRequests = []; const send = ws.send.bind(ws);"
      "ws.send = (t) => { window.sentRequests.push(JSON.parse(t)); send(t); };");
  const auto last_job = [&] {
    const json sent = page.script("return window.sentRequests;");
    return sent.empty() ? json() : sent.back().value("job", json());
  };
  page.script("document.querySelector('details').open = true;");
  page.click("#submit-chamfer");
  ASSERT_TRUE(page.wait_text("state", "ready")) << page.text("message");
  json job = last_job();
  EXPECT_EQ(job["edge"], "inner") << job.dump();
  EXPECT_EQ(job["side"], "upper") << job.dump();
  EXPECT_EQ(job["drill_tilt_deg"], 0.0) << job.dump();
  EXPECT_EQ(job["drill_azimuth_deg"], 0.0) << job.dump();
  EXPECT_EQ(job["eccentricity"], 0.0) << job.dump();
  // Another edge, side, tilt and eccentricity from the form's own fields.
  page.script(
      "const f = document.getElementById('chamfer');"
      "f.elements.edge.value = 'outer'; f.elements.side.value = 'lower';"
      "f.elements.drill_tilt_deg.value = '10'; f.elements.drill_azimuth_deg.value = '90';"
      "f.elements.eccentricity.value = '1.5';");
  page.click("#submit-chamfer");
  EXPECT_TRUE(wait_for("message", [](const std::string& t) { return t.rfind("submit:", 0) == 0; }));
  job = last_job();
  EXPECT_EQ(job["edge"], "outer") << job.dump();
  EXPECT_EQ(job["side"], "lower") << job.dump();
  EXPECT_EQ(job["drill_tilt_deg"], 10.0) << job.dump();
  EXPECT_EQ(job["drill_azimuth_deg"], 90.0) << job.dump();
  EXPECT_EQ(job["eccentricity"], 1.5) << job.dump();
  SocketClient sock(socket_);
  const json by_socket = sock.request({{"cmd", "submit"}, {"job", job}});
  std::cout << "[ measured ] the form's job " << job.dump()
            << " over the socket: " << by_socket.dump() << "; on the page: " << page.text("message")
            << "\n";
  EXPECT_EQ(page.text("message").rfind("submit: ok", 0) == 0, by_socket.value("ok", false))
      << page.text("message") << " against " << by_socket.dump();
  // A tilt outside [0, 90): the service's refusal, naming it, shown on the page.
  page.script("document.getElementById('chamfer').elements.drill_tilt_deg.value = '95';");
  page.script("document.getElementById('message').textContent = '';");
  page.click("#submit-chamfer");
  EXPECT_TRUE(wait_for("message", [](const std::string& t) { return !t.empty(); }));
  EXPECT_EQ(page.text("message").rfind("submit: ", 0), 0u) << page.text("message");
  EXPECT_NE(page.text("message").find("95"), std::string::npos) << page.text("message");
  EXPECT_EQ(page.text("message").find("submit: ok"), std::string::npos) << page.text("message");
}

}  // namespace

namespace truth {  // issue 33: the operator's screen tells the machine's truth

// printf("%.*f"): the page's toFixed for the values compared here.
std::string fixed(double v, int places) {
  char out[64];
  std::snprintf(out, sizeof out, "%.*f", places, v);
  return out;
}

// Waits until the status says the motion is at rest under a hold; returns that status.
json rest_under_hold(SocketClient& sock) {
  json s;
  for (int i = 0; i < 400; ++i) {
    s = sock.request({{"cmd", "status"}});
    if (s["state"] == "holding" && s["feed_mm_per_min"].get<double>() == 0.0) break;
    std::this_thread::sleep_for(50ms);
  }
  return s;
}

// A G20 job with a tool length offset (G43 H1, 50 mm in the tool table), held past X58.143 mm
// on its way along Y0.5 Z-0.125 in to X4 (issue 33's point: 58.143, 12.700, 46.825 mm machine,
// the tool length inside, about X2.289 Y0.5 Z-0.125 in work coordinates): the DRO shows inches with
// its axis names, work and machine coordinates, the tool length apart; the machine state panel the
// program's spindle, coolant and tool. The numbers the test expects come from the program and the
// tool table it wrote (work = machine − tool length, in inches), not from the service's own DRO.
TEST_F(BrowserPage, DroShowsAG20JobInInchesWithAxisNamesAndTheToolLengthApart) {
  write("tool.tbl", "T1 P1 Z50 D6 ;ball\n");
  const std::string machine =
      write("machine.toml", "[program]\ntool_table = \"" + (dir_ / "tool.tbl").string() +
                                "\"\nstart_mm = [0.0, 0.0, 100.0]\n");
  WebDriver& page = open("machine = \"" + machine + "\"\n");
  const std::string program = write("g20.ngc",
                                    "G20 G90 G17\nT1 M6\nG43 H1\nM3 S1000\nM8\nG0 X0 Y0 Z0.5\n"
                                    "G1 Z-0.125 F10\nG1 Y0.5 F20\nG1 X4\nG1 X5\nM5 M9\nM2\n");
  SocketClient sock(socket_);
  ASSERT_TRUE(sock.request({{"cmd", "submit"}, {"job", {{"path", program}}}}).value("ok", false));
  ASSERT_TRUE(sock.request({{"cmd", "start"}}).value("ok", false));
  json s;
  for (int i = 0; i < 3000; ++i) {  // about 12 s of motion to X58.143 mm
    s = sock.request({{"cmd", "status"}});
    if (s["position"].is_array() && s["position"][0].get<double>() > 58.143) break;
    std::this_thread::sleep_for(20ms);
  }
  ASSERT_TRUE(sock.request({{"cmd", "hold"}}).value("ok", false));
  s = rest_under_hold(sock);
  ASSERT_EQ(s["state"], "holding") << s.dump();
  const double x_mm = s["position"][0].get<double>(), y_mm = s["position"][1].get<double>(),
               z_mm = s["position"][2].get<double>();
  // On line 9 (G1 X4): the machine point holds the tool length.
  EXPECT_NEAR(z_mm, -0.125 * 25.4 + 50.0, 1e-9) << s.dump();
  EXPECT_NEAR(y_mm, 0.5 * 25.4, 1e-9) << s.dump();
  EXPECT_GT(x_mm, 58.143);
  EXPECT_LT(x_mm, 4 * 25.4);  // still on line 9
  ASSERT_TRUE(page.wait_text("dro-units", "inch")) << page.text("dro-units");
  EXPECT_TRUE(page.wait_text("dro-wx", fixed(x_mm / 25.4, 4))) << page.text("dro-wx");
  EXPECT_EQ(page.text("dro-wy"), "0.5000");
  EXPECT_EQ(page.text("dro-wz"), "-0.1250");              // the program's Z, not the machine's
  EXPECT_EQ(page.text("dro-mz"), fixed(z_mm / 25.4, 4));  // 1.8435: the tool length inside
  EXPECT_EQ(page.text("dro-mx"), fixed(x_mm / 25.4, 4));
  const json axes = page.script(
      "return Array.from(document.querySelectorAll('.dro-table th.axis')).map((th) => "
      "th.textContent);");
  EXPECT_EQ(axes, json({"X", "Y", "Z"}));
  EXPECT_EQ(page.text("dro-tlo"), "X0.0000 Y0.0000 Z1.9685 inch (G43 H1)");
  EXPECT_EQ(page.text("dro-offset"), "X0.0000 Y0.0000 Z0.0000 inch");
  EXPECT_EQ(page.text("dro-source"), "commanded by ncd");
  EXPECT_EQ(page.text("spindle"), "clockwise (M3), S1000 rpm");
  EXPECT_EQ(page.text("coolant"), "flood (M8)");
  EXPECT_EQ(page.text("tool").rfind("T1 · length offset 50.000 mm (H1)", 0), 0u)
      << page.text("tool");
  // The listing marks line 9, ncd's commanded line (no link here).
  EXPECT_TRUE(page.wait_text("listing-line", "line 9 · commanded by ncd"))
      << page.text("listing-line");
  EXPECT_EQ(page.script("return document.querySelector('#listing li.exec').textContent;"), "G1 X4");
  std::cout << "[ measured ] G20 DRO: work " << page.text("dro-wx") << " " << page.text("dro-wy")
            << " " << page.text("dro-wz") << " in, machine " << page.text("dro-mx") << " "
            << page.text("dro-my") << " " << page.text("dro-mz") << " in; socket " << s["position"]
            << " mm\n";
  // The screenshot of the DRO (docs/img/dashboard-dro.png only with NCD_UPDATE_SCREENSHOT=1,
  // as the dashboard's own).
  const std::string png = page.screenshot_png();
  EXPECT_EQ(png.substr(1, 3), "PNG");
  const char* update = std::getenv("NCD_UPDATE_SCREENSHOT");
  const fs::path shot = update != nullptr && std::string(update) == "1"
                            ? fs::path(NCD_SOURCE_DIR) / "docs" / "img" / "dashboard-dro.png"
                            : fs::current_path() / "dashboard-dro.png";
  std::ofstream(shot, std::ios::binary) << png;
  ASSERT_TRUE(sock.request({{"cmd", "stop"}}).value("ok", false));
}

// A square of 20 mm at F600 with exact stops (G61: each corner a stop, each side its own line),
// streamed over grbl `ack` to `ncd sim-controller --report-line-numbers` with N words on the
// blocks ([encoder] numbers = true). While it runs, the page is read at once (one script): the
// status's Ln:, the block number the service matched it to and the listing's marked line. After
// the job, the simulated controller's log gives the move it executed with that N: the side of
// the square its start lies on is the source line, found by the test from the program's
// geometry. The marked line must be that line, labelled as the controller's.
TEST_F(BrowserPage, ListingMarksTheLineTheControllerReportsExecuting) {
  const std::string port_path = (dir_ / "cnc").string();
  const std::string machine =
      write("machine.toml",
            "period_s = 0.004\nmax_feed_mm_per_min = 6000.0\n\n[link]\ndevice = \"" + port_path +
                "\"\nbaud = 115200\nframe = \"8N1\"\nflow = \"none\"\nprotocol = "
                "\"ack\"\neob = \"lf\"\npercent = false\ndialect = \"grbl\"\n"
                "rx_buffer_bytes = 128\n\n[encoder]\nmax_block_s = 0.5\nnumbers = true\n");
  const fs::path sim_log = dir_ / "sim.json";
  ncd::test::Process controller(
      {NCD_EXE, "sim-controller", "--machine", machine, "--report-line-numbers", "--log",
       sim_log.string(), "--no-machine-safety"},
      (dir_ / "controller.out").string(), (dir_ / "controller.err").string());
  ASSERT_TRUE(ncd::test::wait_for_path(port_path, 10.0)) << slurp(dir_ / "controller.err");
  WebDriver& page = open("machine = \"" + machine + "\"\n");
  const std::string program = write("square.ngc",
                                    "G21 G90 G17 G61\nG0 X0 Y0 Z5\nG1 Z0 F600\nG1 X20 Y0\n"
                                    "G1 X20 Y20\nG1 X0 Y20\nG1 X0 Y0\nG0 Z5\nM2\n");
  SocketClient sock(socket_);
  const json submitted = sock.request({{"cmd", "submit"}, {"job", {{"path", program}}}});
  ASSERT_TRUE(submitted.value("ok", false)) << submitted.dump() << slurp(err_);
  ASSERT_TRUE(sock.request({{"cmd", "start"}}).value("ok", false)) << slurp(err_);
  std::vector<json> samples;
  for (int i = 0; i < 1200; ++i) {
    const json q = page.script(
        "const s = lastStatus || {}; const q = s.controller_progress;"
        "const li = document.querySelector('#listing li.exec');"
        "return {state: s.state, n: q ? q.number : null, source: q ? q.source : null,"
        " ln: s.controller ? s.controller.line_number : null,"
        " work: s.controller ? s.controller.work_mm : null, dro: s.dro,"
        " marked: li ? Array.prototype.indexOf.call(li.parentNode.children, li) + 1 : null,"
        " label: document.getElementById('listing-line').textContent};");
    if (q["source"] == "controller (Ln:)") samples.push_back(q);
    if (q["state"] == "done" || q["state"] == "error" || q["state"] == "stopped") break;
    std::this_thread::sleep_for(100ms);
  }
  const json end = sock.request({{"cmd", "status"}});
  ASSERT_EQ(end["state"], "done") << end.dump() << slurp(err_);
  controller.signal(SIGTERM);
  ASSERT_EQ(controller.wait(30.0), 0) << slurp(dir_ / "controller.err");
  const json log = json::parse(slurp(sim_log));
  // The move with each N: where it starts (the previous move's end) and where it ends.
  std::map<long, std::pair<std::array<double, 3>, std::array<double, 3>>> moves;
  std::array<double, 3> at{0, 0, 0};
  for (const json& m : log["moves"]) {
    const std::array<double, 3> p{m["p"][0].get<double>(), m["p"][1].get<double>(),
                                  m["p"][2].get<double>()};
    if (m["n"].is_number()) moves[m["n"].get<long>()] = {at, p};
    at = p;
  }
  // The side of the square a point a hair past the move's start lies on: lines 4 to 7.
  const auto side = [](const std::array<double, 3>& a, const std::array<double, 3>& b) {
    const double len = std::hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
    if (len < 1e-9) return 0;
    const double x = a[0] + 1e-4 * (b[0] - a[0]) / len, y = a[1] + 1e-4 * (b[1] - a[1]) / len;
    const double z = a[2] + 1e-4 * (b[2] - a[2]) / len;
    const double tol = 2e-3;  // grbl's 3 decimals
    if (std::abs(z) > tol) return 0;
    if (std::abs(y) < tol && x > 0 && x < 20) return 4;
    if (std::abs(x - 20) < tol && y > 0 && y < 20) return 5;
    if (std::abs(y - 20) < tol && x > 0 && x < 20) return 6;
    if (std::abs(x) < tol && y > 0 && y < 20) return 7;
    return 0;
  };
  int checked = 0;
  std::set<int> lines;
  for (const json& q : samples) {
    // The DRO is the controller's: its work position, in mm (no offsets in this program).
    ASSERT_TRUE(q["dro"].is_object()) << q.dump();
    EXPECT_EQ(q["dro"]["source"], "controller") << q.dump();
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(q["dro"]["machine"][a].get<double>(), q["work"][a].get<double>(), 1e-9)
          << q.dump();
    }
    ASSERT_TRUE(q["n"].is_number() && q["ln"].is_number()) << q.dump();
    EXPECT_EQ(q["n"], q["ln"]) << q.dump();  // the block is the one grbl named
    const auto move = moves.find(q["n"].get<long>());
    ASSERT_NE(move, moves.end()) << "N" << q["n"] << " is not in the controller's log";
    const int line = side(move->second.first, move->second.second);
    if (line == 0) continue;  // the plunge, the rapids: not on a side
    EXPECT_EQ(q["marked"], line) << q.dump();
    EXPECT_EQ(q["label"], "line " + std::to_string(line) + " · executing, controller (Ln:)")
        << q.dump();
    lines.insert(line);
    ++checked;
  }
  std::cout << "[ measured ] " << samples.size() << " page readings with Ln:, " << checked
            << " on a side of the square; lines seen:";
  for (int l : lines) std::cout << " " << l;
  std::cout << "\n";
  EXPECT_GE(checked, 5);
  EXPECT_GE(lines.size(), 3u);
}

// The page's XY canvas: how many pixels are the programmed path's grey (#9ca3af).
int grey_pixels(WebDriver& page) {
  return page
      .script(
          "const c = document.getElementById('xy'); const d = c.getContext('2d')"
          ".getImageData(0, 0, c.width, c.height).data; let n = 0;"
          "for (let k = 0; k < d.length; k += 4) if (d[k] === 0x9c && d[k + 1] === 0xa3 && "
          "d[k + 2] === 0xaf) ++n; return n;")
      .get<int>();
}

// Waits for the page to hold the programmed path of `job` and to have drawn it, in state
// ready (before any start).
void expect_preview_before_start(WebDriver& page, const std::string& job) {
  bool drawn = false;
  json state;
  for (int i = 0; i < 600 && !drawn; ++i) {
    state = page.script(
        "return {job: program && program.job, points: program ? program.points.length : 0,"
        " state: lastStatus && lastStatus.state, status_job: lastStatus && lastStatus.job};");
    drawn = state["job"] == job && state["status_job"] == job && state["points"].get<int>() > 10 &&
            grey_pixels(page) > 200;
    if (!drawn) std::this_thread::sleep_for(50ms);
  }
  EXPECT_TRUE(drawn) << state.dump() << " grey pixels " << grey_pixels(page);
  EXPECT_EQ(state["state"], "ready") << state.dump();
}

// A job submitted over the control socket (not from the page): its path is drawn before start.
TEST_F(BrowserPage, PreviewDrawnBeforeStartForASocketSubmit) {
  WebDriver& page = open();
  ASSERT_TRUE(page.wait_text("state", "idle"));
  EXPECT_EQ(grey_pixels(page), 0);
  const std::string program = write("slow.ngc", kProgram);
  SocketClient sock(socket_);
  ASSERT_TRUE(sock.request({{"cmd", "submit"}, {"job", {{"path", program}}}}).value("ok", false));
  expect_preview_before_start(page, program);
  EXPECT_EQ(page.script("return program.listing.length;"), 8);
}

// A chamfer made from parameters (the service generates its path): drawn before start; it has
// no program text, and the listing says so.
TEST_F(BrowserPage, PreviewDrawnBeforeStartForAChamfer) {
  WebDriver& page = open();
  ASSERT_TRUE(page.wait_text("state", "idle"));
  SocketClient sock(socket_);
  const json r = sock.request({{"cmd", "submit"},
                               {"job",
                                {{"pipe_radius", 18},
                                 {"drill_radius", 13},
                                 {"ball_radius", 3},
                                 {"width", 0.7},
                                 {"feed", 300}}}});
  ASSERT_TRUE(r.value("ok", false)) << r.dump();
  expect_preview_before_start(page, r["job"].get<std::string>());
  EXPECT_TRUE(page.wait_text("listing-line", "no program text (a generated or JSON path)"));
}

// A job submitted over MQTT (a real mosquitto; the operator's command topic): drawn before
// start on the machine's own page.
TEST_F(BrowserPage, PreviewDrawnBeforeStartForAnMqttSubmit) {
  if (const std::string why = ncd::test::Broker::missing(); !why.empty()) GTEST_SKIP() << why;
  ncd::test::Broker broker(dir_ / "broker");
  ASSERT_TRUE(broker.start()) << broker.log();
  const std::string root = "ncd/cell1/m1/";
  open("token = \"t0k\"\n[mqtt]\nbroker = \"" + broker.url() + "\"\nusername = \"" +
       ncd::test::kMachine.name + "\"\npassword = \"" + ncd::test::kMachine.password +
       "\"\ntopic_root = \"" + root + "\"\nstatus_hz = 10\n");
  WebDriver& page = *page_;
  page.script("localStorage.setItem('ncd-token', 't0k'); location.reload();");
  ASSERT_TRUE(page.wait_text("conn", "connected"));
  ASSERT_TRUE(page.wait_text("state", "idle")) << page.text("state");
  ncd::test::Watcher ops(broker.url(), "ops-web", ncd::test::kOperator,
                         {root + "reply", root + "online"});
  const std::string program = write("slow.ngc", kProgram);
  json reply;
  for (int attempt = 0; attempt < 50 && reply.is_null(); ++attempt) {  // until the bridge is up
    ops.publish(root + "cmd", {{"cmd", "submit"},
                               {"job", {{"path", program}}},
                               {"token", "t0k"},
                               {"id", "s" + std::to_string(attempt)}});
    for (int i = 0; i < 10 && reply.is_null(); ++i) {
      auto m = ops.next(0.2);
      if (m && m->get_topic() == root + "reply") reply = json::parse(m->to_string());
    }
  }
  ASSERT_TRUE(reply.value("ok", false)) << reply.dump() << slurp(err_);
  expect_preview_before_start(page, program);
}

}  // namespace truth
