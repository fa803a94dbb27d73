// The browser tests' tools (tests/web): an HTTP/1.1 request on loopback, a free port, a program
// on PATH, and chromedriver's W3C WebDriver protocol over HTTP driving a headless Chromium.
#pragma once

#include <unistd.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/core/detail/base64.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace ncd::test {

// A request and reply over HTTP/1.1 on 127.0.0.1:port; the status code and the body.
inline std::pair<int, std::string> http_request(std::uint16_t port, boost::beast::http::verb verb,
                                                const std::string& target,
                                                const std::string& body = "",
                                                const std::string& origin = "") {
  boost::asio::io_context io;
  boost::beast::tcp_stream stream(io);
  stream.connect(boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
  boost::beast::http::request<boost::beast::http::string_body> req{verb, target, 11};
  req.set(boost::beast::http::field::host, "127.0.0.1:" + std::to_string(port));
  if (!origin.empty()) req.set(boost::beast::http::field::origin, origin);
  if (!body.empty()) {
    req.set(boost::beast::http::field::content_type, "application/json");
    req.body() = body;
  }
  req.prepare_payload();
  boost::beast::http::write(stream, req);
  boost::beast::flat_buffer buffer;
  boost::beast::http::response_parser<boost::beast::http::string_body> parser;
  parser.body_limit(64 << 20);
  boost::beast::http::read(stream, buffer, parser);
  return {static_cast<int>(parser.get().result_int()), parser.get().body()};
}

// A free TCP port on loopback (the kernel's choice, released at once).
inline std::uint16_t free_port() {
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor a(
      io, boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  return a.local_endpoint().port();
}

// The first executable of `names` found on PATH; empty if none.
inline std::string find_program(std::initializer_list<const char*> names) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/bin");
  std::vector<std::string> list;
  for (std::string d; std::getline(dirs, d, ':');) list.push_back(d);
  for (const char* name : names) {
    for (const auto& d : list) {
      const std::filesystem::path p = std::filesystem::path(d) / name;
      if (::access(p.c_str(), X_OK) == 0) return p.string();
    }
  }
  return "";
}

// chromedriver's W3C WebDriver protocol over HTTP.
class WebDriver {
 public:
  WebDriver(std::uint16_t port, const std::string& chromium, const std::string& profile)
      : port_(port) {
    for (int i = 0; i < 300; ++i) {  // chromedriver may still be starting
      try {
        if (get("/status")["value"]["ready"] == true) break;
      } catch (const std::exception&) {
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    const nlohmann::json caps = {
        {"capabilities",
         {{"alwaysMatch",
           {{"browserName", "chrome"},
            {"goog:chromeOptions",
             {{"binary", chromium},
              {"args",
               {"--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1400,1300", "--user-data-dir=" + profile}}}}}}}}};
    const nlohmann::json r = post("/session", caps);
    session_ = r["value"].value("sessionId", std::string());
    if (session_.empty()) throw std::runtime_error("no WebDriver session: " + r.dump());
  }
  ~WebDriver() {
    try {
      call(boost::beast::http::verb::delete_, "/session/" + session_, "");
    } catch (const std::exception&) {
    }
  }
  void go(const std::string& url) { post(path("/url"), {{"url", url}}); }
  std::string element(const std::string& css) {
    const nlohmann::json r = post(path("/element"), {{"using", "css selector"}, {"value", css}});
    const std::string id = r["value"].value("element-6066-11e4-a52e-4f735466cecf", std::string());
    if (id.empty()) throw std::runtime_error("no element " + css + ": " + r.dump());
    return id;
  }
  void click(const std::string& css) {
    post(path("/element/" + element(css) + "/click"), nlohmann::json::object());
  }
  void type(const std::string& css, const std::string& text) {
    post(path("/element/" + element(css) + "/value"), {{"text", text}});
  }
  nlohmann::json script(const std::string& body,
                        const nlohmann::json& args = nlohmann::json::array()) {
    return post(path("/execute/sync"), {{"script", body}, {"args", args}})["value"];
  }
  // The text of the element with this id (its DOM text, before CSS transforms).
  std::string text(const std::string& id) {
    const nlohmann::json v =
        script("return document.getElementById(arguments[0]).textContent;", {id});
    return v.is_string() ? v.get<std::string>() : "";
  }
  // Waits up to timeout_s for the element's text to be `want`.
  bool wait_text(const std::string& id, const std::string& want, double timeout_s = 30.0) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      if (text(id) == want) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }
  std::string screenshot_png() {
    const std::string b64 = get(path("/screenshot"))["value"].get<std::string>();
    std::string out(boost::beast::detail::base64::decoded_size(b64.size()), '\0');
    const auto n = boost::beast::detail::base64::decode(out.data(), b64.data(), b64.size());
    out.resize(n.first);
    return out;
  }

 private:
  std::string path(const std::string& tail) const { return "/session/" + session_ + tail; }
  nlohmann::json call(boost::beast::http::verb verb, const std::string& target,
                      const std::string& body) {
    const auto [code, text] = http_request(port_, verb, target, body);
    nlohmann::json r = nlohmann::json::parse(text);
    if (code != 200) throw std::runtime_error(target + ": " + text.substr(0, 400));
    return r;
  }
  nlohmann::json get(const std::string& target) {
    return call(boost::beast::http::verb::get, target, "");
  }
  nlohmann::json post(const std::string& target, const nlohmann::json& body) {
    return call(boost::beast::http::verb::post, target, body.dump());
  }
  std::uint16_t port_;
  std::string session_;
};

}  // namespace ncd::test
