// A real mosquitto broker for the fleet tests, started on a free loopback port with its own
// config in a test folder: no anonymous clients, a password file made with mosquitto_passwd, an
// ACL that gives each machine its own topic root (user m1: ncd/cell1/m1/#) and the operator
// (user ops) read access to everything and write access to the command topics. The broker keeps
// its sessions on disk (persistence, saved on every change), so a subscriber's session survives
// a SIGKILL and a restart.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "tests/common/process.hpp"

namespace ncd::test {

// The full path of a program in PATH or in the usual sbin folders; empty when absent.
inline std::string find_program(const std::string& name) {
  std::string dirs = "/usr/sbin:/usr/local/sbin:/sbin";
  if (const char* path = std::getenv("PATH")) dirs = std::string(path) + ":" + dirs;
  std::size_t start = 0;
  while (start <= dirs.size()) {
    const std::size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::filesystem::path p = std::filesystem::path(dirs.substr(start, end - start)) / name;
    if (!p.parent_path().empty() && ::access(p.c_str(), X_OK) == 0) return p.string();
    start = end + 1;
  }
  return "";
}

// A TCP port on 127.0.0.1 that was free a moment ago (the kernel's choice).
inline int free_loopback_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t n = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
  ::close(fd);
  return ntohs(a.sin_port);
}

inline bool port_accepts(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  const bool ok = ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  ::close(fd);
  return ok;
}

struct BrokerUser {
  std::string name, password;
};
inline const BrokerUser kMachine{"m1", "m1-secret"}, kOtherMachine{"m2", "m2-secret"},
    kOperator{"ops", "ops-secret"};

// mosquitto_passwd -b for each user into a new password file; throws when the tool fails.
inline void write_broker_passwords(const std::filesystem::path& file,
                                   const std::vector<BrokerUser>& users) {
  const std::string tool = find_program("mosquitto_passwd");
  for (std::size_t k = 0; k < users.size(); ++k) {
    const std::string cmd = tool + (k == 0 ? " -c" : "") + " -b " + file.string() + " " +
                            users[k].name + " " + users[k].password + " >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0) throw std::runtime_error("mosquitto_passwd failed");
  }
}

// One mosquitto process on the config `dir/mosquitto.conf`, restartable: each run logs to its own
// `mosquitto.N.err`. start() waits (10 s at most) until every given port accepts connections.
class MosquittoProcess {
 public:
  explicit MosquittoProcess(std::filesystem::path dir) : dir_(std::move(dir)) {}
  ~MosquittoProcess() { kill(); }
  bool start(const std::vector<int>& ports) {
    ++runs_;
    process_ =
        std::make_unique<Process>(std::vector<std::string>{find_program("mosquitto"), "-c",
                                                           (dir_ / "mosquitto.conf").string()},
                                  (dir_ / "mosquitto.out").string(), log_path().string());
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (std::chrono::steady_clock::now() < end) {
      bool all = true;
      for (const int port : ports) all = all && port_accepts(port);
      if (all) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  // SIGKILL: no clean shutdown, no last save of the database.
  void kill() {
    if (!process_) return;
    process_->signal(SIGKILL);
    process_->wait(10);
    process_.reset();
  }
  pid_t pid() const { return process_ ? process_->pid() : -1; }
  // The standard error of the latest run.
  std::string log() const {
    std::ifstream in(log_path());
    return std::string(std::istreambuf_iterator<char>(in), {});
  }

 private:
  std::filesystem::path log_path() const {
    return dir_ / ("mosquitto." + std::to_string(runs_) + ".err");
  }
  std::filesystem::path dir_;
  int runs_ = 0;
  std::unique_ptr<Process> process_;
};

class Broker {
 public:
  // Why the tests cannot run here ("" when they can).
  static std::string missing() {
    if (find_program("mosquitto").empty() || find_program("mosquitto_passwd").empty()) {
      return "mosquitto is not installed (apt-get install mosquitto mosquitto-clients, or "
             "scripts/install-deps.sh); the fleet tests need a real broker";
    }
    return "";
  }

  explicit Broker(const std::filesystem::path& dir)
      : dir_(dir), port_(free_loopback_port()), mosquitto_(dir) {
    std::filesystem::create_directories(dir_ / "db");
    const std::string passwd = (dir_ / "passwd").string();
    write_broker_passwords(passwd, {kMachine, kOtherMachine, kOperator});
    std::ofstream(dir_ / "acl") << "# each machine: its own root; the operator: all, and commands\n"
                                   "pattern readwrite ncd/cell1/%u/#\n"
                                   "user ops\n"
                                   "topic read ncd/#\n"
                                   "topic write ncd/+/+/cmd\n";
    std::ofstream conf(dir_ / "mosquitto.conf");
    conf << "listener " << port_ << " 127.0.0.1\n"
         << "allow_anonymous false\n"
         << "password_file " << passwd << "\n"
         << "acl_file " << (dir_ / "acl").string() << "\n"
         << "persistence true\n"
         << "persistence_location " << (dir_ / "db").string() << "/\n"
         << "autosave_interval 1\n"
         << "autosave_on_changes true\n"
         << "log_dest stderr\n";
    if (::geteuid() == 0) conf << "user root\n";  // keep access to the files of the test folder
  }

  // Starts mosquitto and waits (10 s at most) until it accepts connections.
  bool start() { return mosquitto_.start({port_}); }
  // SIGKILL: no clean shutdown, no last save of the database.
  void kill() { mosquitto_.kill(); }
  int port() const { return port_; }
  std::string url() const { return "tcp://127.0.0.1:" + std::to_string(port_); }
  std::string log() const { return mosquitto_.log(); }

 private:
  std::filesystem::path dir_;
  int port_;
  MosquittoProcess mosquitto_;
};

}  // namespace ncd::test
