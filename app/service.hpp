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
#include "comms/dnc_sender.hpp"
#include "core/geometry.hpp"
#include "motion/cycle.hpp"
#include "toolpath/path.hpp"

namespace ncd::app {

// The default control endpoint: unix:DIR/ncd.sock in the runtime directory, DIR =
// $RUNTIME_DIRECTORY (systemd's RuntimeDirectory=), else $XDG_RUNTIME_DIR, else /tmp. The socket
// is made with mode 0660: its owner and group may drive the machine, nobody else.
std::string default_listen();

// `ncd serve --config FILE.toml`: every key optional.
struct ServiceConfig {
  std::string listen = default_listen();  // TCP on loopback by config; elsewhere a token
  std::optional<std::string> token;       // required on every request when set
  std::string machine_file;               // machine TOML; empty: the documented defaults
  MachineConfig machine;                  // loaded from machine_file
  motion::ClockKind clock = motion::ClockKind::Wall;  // "simulated": run jobs without sleeping
  bool realtime = true;                               // ask for SCHED_FIFO and locked memory
  std::string source = "defaults";
};

// Throws InputError naming the file, the key and the value.
ServiceConfig load_service_config(const std::string& path);
// The same on TOML text already in memory; `name` stands for the file in messages.
ServiceConfig parse_service_config(const std::string& text, const std::string& name);

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
  // Streaming: the motion has ended; the controller is still receiving its blocks.
  // Stopped: ended early by `stop` or by a shutdown, at rest on the path (stop_ says where).
  enum class State { Idle, Ready, Running, Holding, Streaming, Done, Stopped, Error };
  static const char* name(State s);

  nlohmann::json submit(const nlohmann::json& req);
  nlohmann::json start();
  void drain();  // pops setpoints on a 1 ms timer while a job runs (drain_setpoints)
  void drain_setpoints();
  std::optional<double> time_left_s() const;
  void finish_job();  // the cycle has ended: close the setpoints file, set the state
  void start_stream(const Vec3& start_mm);  // the encoder and the sender thread of the job
  void link_hold(bool hold);                // the sender's hold callback, on the I/O thread
  void await_stream();  // after the cycle: wait (on a timer) for the sender to finish
  void end_job();       // the job is over, motion and transfer
  nlohmann::json stream_status() const;
  void require_active(const char* cmd) const;
  motion::JobConfig job_config() const;
  void fail_job(const std::string& why);  // any exception while a job runs: state error
  nlohmann::json stop_report() const;     // why and where a stopped job stopped

  boost::asio::io_context& io_;
  ServiceConfig config_;
  State state_ = State::Idle;
  std::string job_name_, error_;
  MachineConfig job_machine_;  // the machine for this job (a chamfer's ball radius applied)
  bool interference_allowed_ = false;
  Vec3 start_mm_ = Vec3::Zero();  // where the job's path starts
  std::string stop_why_;          // set by `stop` or a shutdown
  double moving_s_ = 0.0;         // time with the tool moving, s (the estimate of time_left_s)
  std::optional<double> held_time_left_s_;  // frozen while holding
  std::unique_ptr<toolpath::Path> path_;
  std::string setpoints_file_;
  std::string port_;  // the DNC port of the submitted job; empty: no streaming
  struct LiveStream;  // encoder → queue → sender thread (service.cpp)
  std::unique_ptr<LiveStream> stream_;
  bool held_by_link_ = false;
  State final_state_ = State::Done;  // what the job ends as once the stream is done
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
