// The fixture of the `ncd serve` tests (serve_test.cpp, serve_hardening_test.cpp): the service
// as a real process on a Unix socket in the test folder, and a line-oriented client.
#pragma once

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "tests/app/cli_fixture.hpp"

namespace ncd::test {

// A line-oriented client on a Unix socket.
class ServeClient {
 public:
  explicit ServeClient(const std::string& path) {
    using namespace std::chrono_literals;
    fd_ = socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    for (int i = 0; i < 400; ++i) {  // the service may still be starting
      if (connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return;
      std::this_thread::sleep_for(25ms);
    }
    ADD_FAILURE() << "cannot connect to " << path;
  }
  ~ServeClient() { close(fd_); }
  ServeClient(const ServeClient&) = delete;
  ServeClient& operator=(const ServeClient&) = delete;

  bool send_line(const std::string& line) {
    const std::string s = line + "\n";
    return write(fd_, s.data(), s.size()) == static_cast<ssize_t>(s.size());
  }
  // The next line, or "" after 20 s.
  std::string read_line() {
    for (;;) {
      const auto nl = buf_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return line;
      }
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 20000) <= 0) return "";
      char tmp[4096];
      const ssize_t n = read(fd_, tmp, sizeof tmp);
      if (n <= 0) return "";
      buf_.append(tmp, static_cast<std::size_t>(n));
    }
  }
  nlohmann::json request(const nlohmann::json& req) { return request_line(req.dump()); }
  nlohmann::json request_line(const std::string& line) {
    if (!send_line(line)) return nlohmann::json{{"ok", false}, {"error", "send failed"}};
    const std::string reply = read_line();
    EXPECT_FALSE(reply.empty()) << "no reply to " << line;
    return reply.empty() ? nlohmann::json{{"ok", false}, {"error", "no reply"}}
                         : nlohmann::json::parse(reply);
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

class ServeFixture : public Cli {
 protected:
  // Starts `ncd serve` with a config of `clock` ("wall" or "simulated") and `extra` lines on a
  // socket in the test folder; its standard error goes to serve.err.
  void launch(const std::string& clock, const std::string& extra = "") {
    socket_ = (dir_ / "ncd.sock").string();
    const std::string config =
        write("serve.toml", "clock = \"" + clock + "\"\nrealtime = false\n" + extra);
    pid_ = fork();
    if (pid_ == 0) {
      const std::string err = (dir_ / "serve.err").string();
      if (!freopen(err.c_str(), "w", stderr)) _exit(126);
      execl(NCD_EXE, NCD_EXE, "serve", "--config", config.c_str(), "--listen",
            ("unix:" + socket_).c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  bool alive() {
    int status = 0;
    return pid_ > 0 && waitpid(pid_, &status, WNOHANG) == 0;
  }
  // Sends SIGTERM and returns the exit status.
  int terminate() {
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  void TearDown() override {
    if (pid_ > 0) terminate();
    Cli::TearDown();
  }
  // Polls the status every 10 ms until the state is `state` (a failure after `tries`).
  nlohmann::json wait_for(ServeClient& c, const std::string& state, int tries = 3000) {
    nlohmann::json s;
    for (int i = 0; i < tries; ++i) {
      s = c.request({{"cmd", "status"}});
      if (s["state"] == state) return s;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ADD_FAILURE() << "state never became " << state << ": " << s.dump();
    return s;
  }
  static void expect_error(const nlohmann::json& reply, const std::string& part,
                           const std::string& what) {
    EXPECT_FALSE(reply.value("ok", true)) << what << ": " << reply.dump();
    const std::string error = reply.value("error", "");
    EXPECT_NE(error.find(part), std::string::npos) << what << ": " << reply.dump();
    EXPECT_EQ(error.find("internal error"), std::string::npos) << what << ": " << reply.dump();
  }

  std::string socket_;
  pid_t pid_ = -1;
};

}  // namespace ncd::test
