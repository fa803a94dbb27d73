// The ncd service: jobs submitted, started, held, overridden and stopped over the control
// socket, each run by a motion::Cycle. The state machine is explained in service.cpp.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "app/machine_config.hpp"
#include "app/setpoint_sink.hpp"
#include "comms/control_server.hpp"
#include "motion/cycle.hpp"
#include "toolpath/path.hpp"

namespace ncd::app {

// `ncd serve --config FILE.toml`: every key optional.
struct ServiceConfig {
  std::string listen = "tcp:127.0.0.1:7878";  // loopback only unless a token is set
  std::optional<std::string> token;           // required on every request when set
  std::string machine_file;                   // machine TOML; empty: the documented defaults
  MachineConfig machine;                      // loaded from machine_file
  motion::ClockKind clock = motion::ClockKind::Wall;  // "simulated": run jobs without sleeping
  bool realtime = true;                               // ask for SCHED_FIFO and locked memory
  std::string source = "defaults";
};

// Throws InputError naming the file, the key and the value.
ServiceConfig load_service_config(const std::string& path);

class Service : public comms::ControlHandler {
 public:
  Service(boost::asio::io_context& io, const ServiceConfig& config);
  ~Service() override;

  nlohmann::json handle(const nlohmann::json& request) override;
  nlohmann::json status() override;
  // SIGTERM/SIGINT: bring any motion to a jerk-limited stop, end the job cleanly, then call
  // done (on the io_context).
  void shutdown(std::function<void()> done);

 private:
  enum class State { Idle, Ready, Running, Holding, Done, Error };
  static const char* name(State s);

  nlohmann::json submit(const nlohmann::json& req);
  nlohmann::json start();
  void drain();       // pops setpoints on a 1 ms timer while a job runs
  void finish_job();  // the cycle has ended: close the setpoints file, set the state
  void require_active(const char* cmd) const;
  motion::JobConfig job_config() const;

  boost::asio::io_context& io_;
  ServiceConfig config_;
  State state_ = State::Idle;
  std::string job_name_, error_;
  std::unique_ptr<toolpath::Path> path_;
  std::string setpoints_file_;
  std::unique_ptr<SetpointSink> sink_;
  std::unique_ptr<motion::Cycle> cycle_;
  boost::asio::steady_timer timer_;
  std::function<void()> on_idle_;  // shutdown's continuation
  // What the current job did, from its setpoints.
  std::int64_t setpoints_ = 0;
  motion::Setpoint last_{};
  double accel_max_ = 0.0, jerk_max_ = 0.0, feed_max_ = 0.0;
  double override_percent_ = 100.0;
  std::string realtime_;
};

}  // namespace ncd::app
