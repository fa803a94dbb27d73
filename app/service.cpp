// The service's job state machine, run entirely on the I/O thread (the io_context): requests
// from the control socket, the 1 ms drain of the setpoint ring and signals all arrive there, so
// the service's own state needs no lock. The cycle thread is reached only through its atomic
// command flags, its setpoint ring and its seqlocked status.
//
//   idle ──submit──► ready ──start──► running ◄──resume── holding
//     ▲                │                 │  └───hold───────►  │
//     │                │                 ▼                    ▼
//     └──── submit ◄── done / error ◄── (job ends, or stop: a jerk-limited stop on the path)
//
// A submitted job is either {"path": FILE} in any format `ncd replay` reads, or a chamfer
// specification with the parameter names of `ncd chamfer` ("pipe_radius" or "pipe-radius", …).
// "setpoints": FILE in the submit request records the job's setpoints in the replay CSV format.
//
// Live DNC streaming: when the machine file's [link] names a device (or the submit request
// gives "port": DEV; "port": "" turns it off), every setpoint drained from the cycle also goes
// through the block encoder, whose blocks queue for a sender thread that drip-feeds (or
// streams with acknowledgements) the controller. A hold on the link (XOFF or CTS longer than
// xoff_timeout_s, a lost port) holds the motion: the cycle brings it to a jerk-limited stop,
// and it resumes when the link does. The job is done when the motion has ended and the
// controller has every block.
#include "app/service.hpp"

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <thread>

#include "app/chamfer_report.hpp"
#include "app/job_checks.hpp"
#include "app/link_options.hpp"
#include "comms/block_encoder.hpp"
#include "comms/live_blocks.hpp"
#include "comms/transfer_journal.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/json_input.hpp"
#include "toolpath/chamfer.hpp"
#include "toolpath/path_io.hpp"

namespace ncd::app {
namespace {

using nlohmann::json;

constexpr double kLiveMaxBlockS = 0.5;  // longest block when streaming live, s

// A request's field as a number, with the key named in the error.
double number(const json& obj, const std::string& key) {
  if (!obj.contains(key)) throw InputError("\"" + key + "\" is missing");
  if (!obj[key].is_number()) throw InputError("\"" + key + "\" must be a number");
  return obj[key].get<double>();
}

// The chamfer job: the flags of `ncd chamfer` as JSON keys ('-' or '_').
toolpath::Path chamfer_path(const json& spec) {
  json j;
  for (const auto& [k, v] : spec.items()) {
    std::string key = k;
    for (char& c : key) c = c == '-' ? '_' : c;
    j[key] = v;
  }
  static const char* kKeys[] = {"pipe_radius",     "drill_radius", "ball_radius", "width",
                                "tolerance",       "edge",         "side",        "rod_radius",
                                "non_knife_angle", "no_avoid",     "feed",        "spindle",
                                "initial_segments"};
  static const char* kHoleKeys[] = {"drill_tilt_deg", "drill_azimuth_deg", "eccentricity",
                                    "pipe_half_angle_deg", "pipe_thickness"};
  for (const auto& [k, v] : j.items()) {
    if (k == "allow_interference") continue;  // read by submit()
    if (std::find(std::begin(kKeys), std::end(kKeys), k) == std::end(kKeys) &&
        std::find(std::begin(kHoleKeys), std::end(kHoleKeys), k) == std::end(kHoleKeys)) {
      throw InputError("unknown chamfer parameter \"" + k +
                       "\"; the names are those of `ncd chamfer --help`");
    }
  }
  toolpath::ChamferSpec s;
  s.pipe_radius_mm = number(j, "pipe_radius");
  s.drill_radius_mm = number(j, "drill_radius");
  s.ball_radius_mm = number(j, "ball_radius");
  s.width_mm = number(j, "width");
  if (j.contains("tolerance")) s.tolerance_mm = number(j, "tolerance");
  const auto word = [&](const char* key, const char* a, const char* b) {
    if (!j.contains(key)) return true;
    if (!j[key].is_string() || (j[key] != a && j[key] != b)) {
      throw InputError(std::string("\"") + key + "\" must be \"" + a + "\" or \"" + b + "\"");
    }
    return j[key] == a;
  };
  s.edge = word("edge", "inner", "outer") ? toolpath::Edge::Inner : toolpath::Edge::Outer;
  s.side = word("side", "upper", "lower") ? toolpath::Side::Upper : toolpath::Side::Lower;
  if (j.contains("rod_radius")) s.rod_radius_mm = number(j, "rod_radius");
  std::optional<double> nka_deg;
  if (j.contains("non_knife_angle")) {
    nka_deg = number(j, "non_knife_angle");
    s.non_knife_angle_rad = deg_to_rad(*nka_deg);
  }
  if (j.contains("no_avoid")) {
    if (!j["no_avoid"].is_boolean()) throw InputError("\"no_avoid\" must be true or false");
    s.avoid = !j["no_avoid"].get<bool>();
  }
  if (j.contains("initial_segments")) {
    s.initial_segments = static_cast<int>(
        json_integer(j["initial_segments"], toolpath::ChamferLimits::kMinInitialSegments,
                     toolpath::ChamferLimits::kMaxInitialSegments, "\"initial_segments\""));
  }
  // Inclined, eccentric and cone holes (docs/chamfer.md): the names of `ncd chamfer`.
  if (j.contains("drill_tilt_deg")) s.drill_tilt_rad = deg_to_rad(number(j, "drill_tilt_deg"));
  if (j.contains("drill_azimuth_deg")) {
    s.drill_azimuth_rad = deg_to_rad(number(j, "drill_azimuth_deg"));
  }
  if (j.contains("eccentricity")) s.eccentricity_mm = number(j, "eccentricity");
  if (j.contains("pipe_half_angle_deg")) {
    s.pipe_half_angle_rad = deg_to_rad(number(j, "pipe_half_angle_deg"));
  }
  if (j.contains("pipe_thickness")) s.pipe_thickness_mm = number(j, "pipe_thickness");
  toolpath::NgcOptions ngc;
  if (j.contains("feed")) ngc.feed_mm_per_min = number(j, "feed");
  if (j.contains("spindle")) ngc.spindle_rpm = number(j, "spindle");
  require_positive("feed", ngc.feed_mm_per_min);
  const toolpath::ChamferPath path = toolpath::generate_chamfer(s);
  // Its checks and its ball radius travel in the JSON, as for a chamfer file: accept_chamfer()
  // decides at submit, the same way for both.
  return toolpath::read_path_text(chamfer_json(path, ngc, nka_deg, 0.0).dump(), "chamfer job");
}

}  // namespace

ServiceConfig load_service_config(const std::string& path) {
  return parse_service_config(read_input_file(path, "service config, --config"), path);
}

// The encoder, the queue and the sender thread of a streamed job.
struct Service::LiveStream {
  comms::LiveBlocks blocks;
  std::unique_ptr<comms::BlockEncoder> encoder;
  std::unique_ptr<comms::TransferJournal> journal;
  std::unique_ptr<comms::DncSender> sender;
  std::thread thread;
  std::atomic<bool> stop{false};
  std::atomic<bool> done{false};
  std::atomic<std::int64_t> blocks_encoded{0};
  std::atomic<std::int64_t> chars_encoded{0};
  comms::SenderReport report;  // written by the thread before done
  comms::LineSettings line;
  mutable std::mutex mutex;
  std::string last_event;  // guarded by mutex
  ~LiveStream() {
    stop = true;
    if (thread.joinable()) thread.join();
  }
};

const char* Service::name(State s) {
  switch (s) {
    case State::Idle:
      return "idle";
    case State::Ready:
      return "ready";
    case State::Running:
      return "running";
    case State::Streaming:
      return "streaming";
    case State::Holding:
      return "holding";
    case State::Done:
      return "done";
    case State::Stopped:
      return "stopped";
    case State::Error:
      return "error";
  }
  return "error";
}

Service::Service(boost::asio::io_context& io, const ServiceConfig& config)
    : io_(io), config_(config), timer_(io) {}

Service::~Service() {
  timer_.cancel();
  if (cycle_) {
    cycle_->stop();
    cycle_.reset();  // joins
  }
}

motion::JobConfig Service::job_config() const {
  motion::JobConfig j;
  j.limits = job_machine_.limits;
  j.cutting = job_machine_.cutting;
  return j;
}

void Service::require_active(const char* cmd) const {
  if (state_ != State::Running && state_ != State::Holding) {
    throw InputError(std::string(cmd) + ": no job is running (state " + name(state_) + ")");
  }
}

json Service::submit(const json& req) {
  if (state_ == State::Running || state_ == State::Holding || state_ == State::Streaming) {
    throw InputError("submit: a job is running; stop it first");
  }
  if (!req.contains("job") || !req["job"].is_object()) {
    throw InputError("submit needs \"job\": {\"path\": FILE} or a chamfer specification");
  }
  const json& job = req["job"];
  bool allow_interference = false;
  if (const auto allow = job.find("allow_interference"); allow != job.end()) {
    if (!allow->is_boolean()) {
      throw InputError("\"job\".\"allow_interference\" must be true or false");
    }
    allow_interference = allow->get<bool>();
  }
  std::unique_ptr<toolpath::Path> path;
  std::string job_name;
  if (job.contains("path")) {
    for (const auto& [key, value] : job.items()) {
      if (key != "path" && key != "allow_interference") {
        throw InputError("unknown key \"job\".\"" + key +
                         "\" in a path job; it takes \"path\" and \"allow_interference\"");
      }
    }
    if (!job["path"].is_string()) throw InputError("\"job\".\"path\" must be a file name");
    path = std::make_unique<toolpath::Path>(
        toolpath::read_path_file(job["path"], config_.machine.program));
    job_name = job["path"].get<std::string>();
  } else {
    path = std::make_unique<toolpath::Path>(chamfer_path(job));
    job_name = "chamfer";
  }
  std::string port = config_.machine.link.line.device;
  if (req.contains("port")) {
    if (!req["port"].is_string()) {
      throw InputError("\"port\" must be a device name, or \"\" for no streaming");
    }
    port = req["port"];
  }
  std::string setpoints;
  if (req.contains("setpoints")) {
    if (!req["setpoints"].is_string()) throw InputError("\"setpoints\" must be a file name");
    setpoints = req["setpoints"];
    check_output(setpoints, "\"setpoints\"");
  }
  // Before any motion, as `ncd replay` does: the chamfer's checks and tool, the envelope, the
  // size of the run, the port.
  MachineConfig machine = config_.machine;
  const ChamferAcceptance chamfer =
      accept_chamfer(*path, machine, allow_interference, "\"allow_interference\": true");
  check_envelope(*path, machine);
  check_estimate(estimate_run(*path, machine), !setpoints.empty());
  if (!port.empty()) require_serial_port(port, "\"port\"");
  // Build the job once now, so that a path the machine cannot run is refused at submit.
  motion::JobConfig jc;
  jc.limits = machine.limits;
  jc.cutting = machine.cutting;
  (void)motion::Job(*path, jc);
  if (!chamfer.note.empty()) std::cerr << "ncd serve: " << chamfer.note << "\n";
  job_name_ = std::move(job_name);
  job_machine_ = std::move(machine);
  interference_allowed_ = chamfer.interference_allowed;
  port_ = std::move(port);
  setpoints_file_ = std::move(setpoints);
  path_ = std::move(path);
  state_ = State::Ready;
  error_.clear();
  json reply{{"ok", true}, {"state", name(state_)}, {"job", job_name_}};
  if (interference_allowed_) reply["warning"] = chamfer.note;
  return reply;
}

json Service::start() {
  if (state_ != State::Ready) {
    throw InputError(std::string("start: nothing to start (state ") + name(state_) +
                     "); submit a job first");
  }
  if (!port_.empty()) require_serial_port(port_, "\"port\"");  // it may have gone since submit
  auto job = std::make_unique<motion::Job>(*path_, job_config());
  stream_.reset();
  held_by_link_ = false;
  start_mm_ = job->walker().position();
  stop_why_.clear();
  moving_s_ = 0.0;
  held_time_left_s_.reset();
  if (!port_.empty()) start_stream(job->walker().position());
  motion::CycleOptions o;
  o.clock = config_.clock;
  o.realtime = config_.realtime;
  sink_ = std::make_unique<SetpointSink>(setpoints_file_);
  cycle_ = std::make_unique<motion::Cycle>(std::move(job), o);
  setpoints_ = 0;
  accel_max_ = jerk_max_ = feed_max_ = 0.0;
  override_percent_ = 100.0;
  last_ = {};
  realtime_ = cycle_->start().message;
  std::cerr << "ncd serve: job " << job_name_ << " started; " << realtime_ << "\n";
  state_ = State::Running;
  drain();
  return {{"ok", true}, {"state", name(state_)}, {"realtime", realtime_}};
}

void Service::fail_job(const std::string& why) {
  std::cerr << "ncd serve: job " << job_name_ << " failed: " << why << "\n";
  timer_.cancel();
  if (cycle_) cycle_->stop();
  cycle_.reset();  // joins the cycle thread
  if (stream_) {
    stream_->blocks.close();
    stream_.reset();  // stops and joins the sender thread
  }
  sink_.reset();  // removes the setpoints' temporary file
  state_ = State::Error;
  error_ = why;
  end_job();
}

void Service::drain() {
  try {
    drain_setpoints();
  } catch (const std::exception& e) {
    fail_job(std::string("internal error: ") + e.what());
  }
}

void Service::drain_setpoints() {
  if (!cycle_) return;
  motion::Setpoint sp;
  const double period_s = job_machine_.limits.period_s;
  while (cycle_->pop(sp)) {
    ++setpoints_;
    if (sp.v_mm_per_s > 0.0) moving_s_ += period_s;
    last_ = sp;
    accel_max_ = std::max(accel_max_, std::abs(sp.a_mm_per_s2));
    jerk_max_ = std::max(jerk_max_, std::abs(sp.j_mm_per_s3));
    feed_max_ = std::max(feed_max_, sp.v_mm_per_s);
    sink_->write(sp);
    if (stream_) stream_->encoder->push(sp);
  }
  if (cycle_->finished()) {
    while (cycle_->pop(sp)) {
      ++setpoints_, last_ = sp, sink_->write(sp);
      if (stream_) stream_->encoder->push(sp);
    }
    finish_job();
    return;
  }
  timer_.expires_after(std::chrono::milliseconds(1));
  timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) drain();
  });
}

void Service::finish_job() {
  cycle_->join();
  const motion::CycleState end = cycle_->status().state;
  if (end == motion::CycleState::Error) {
    state_ = State::Error;
    error_ = cycle_->error();
  } else if (end == motion::CycleState::Stopped) {
    state_ = State::Stopped;
  } else {
    state_ = State::Done;
  }
  try {
    if (state_ == State::Error) {
      sink_.reset();  // a job in error keeps no setpoints file (its temporary is removed)
    } else {
      sink_->commit();
    }
  } catch (const std::exception& e) {
    state_ = State::Error;
    error_ = e.what();
  }
  const motion::CycleStats& st = cycle_->stats();
  std::cerr << "ncd serve: job " << job_name_ << " motion ended after " << setpoints_
            << " setpoints; " << st.late_wakeups << " late wake-ups, " << st.overruns
            << " overruns, " << st.setpoints_lost << " setpoints lost\n";
  if (stream_) {
    stream_->encoder->finish();
    stream_->blocks.close();
    final_state_ = state_;
    state_ = State::Streaming;
    await_stream();
    return;
  }
  end_job();
}

void Service::end_job() {
  std::cerr << "ncd serve: job " << job_name_ << " " << name(state_) << "\n";
  if (on_idle_) io_.post(on_idle_);
}

void Service::start_stream(const Vec3& start_mm) {
  const LinkConfig& link = config_.machine.link;
  auto ls = std::make_unique<LiveStream>();
  LiveStream* raw = ls.get();
  ls->line = link.line;
  ls->line.device = port_;
  comms::EncoderSettings enc = config_.machine.encoder;
  enc.line = ls->line;
  // Live, a block reaches the controller only when it closes: bound its length in time so the
  // controller's lead stays short (a machine file's max_block_s, else 0.5 s).
  if (enc.max_block_s <= 0.0) enc.max_block_s = kLiveMaxBlockS;
  ls->encoder = std::make_unique<comms::BlockEncoder>(enc, [raw](const comms::EncodedBlock& b) {
    raw->blocks_encoded.fetch_add(1, std::memory_order_relaxed);
    raw->chars_encoded.fetch_add(b.chars, std::memory_order_relaxed);
    raw->blocks.push(b.text);
  });
  motion::Setpoint start;
  start.p = start_mm;
  ls->encoder->push(start);
  if (!link.journal.empty()) {
    comms::JournalState js;
    js.program_sha256 = "live job " + job_name_;
    js.settings = comms::describe(ls->line);
    ls->journal = std::make_unique<comms::TransferJournal>(link.journal, js);
  }
  comms::SenderSettings ss;
  ss.line = ls->line;
  ss.max_queued_chars = link.max_queued_chars;
  ss.rx_buffer_bytes = link.rx_buffer_bytes;
  ss.xoff_timeout_s = link.xoff_timeout_s;
  ss.reconnect_max_s = link.reconnect_max_s;
  ls->sender =
      std::make_unique<comms::DncSender>(ss, ls->blocks, [raw](const comms::SenderEvent& e) {
        if (e.kind != comms::SenderEvent::Kind::Progress) {
          std::cerr << "ncd serve: link: " << e.text << std::endl;
        }
        std::lock_guard lock(raw->mutex);
        raw->last_event = e.text;
      });
  ls->sender->set_journal(ls->journal.get());
  ls->sender->on_hold([this](bool hold) { io_.post([this, hold] { link_hold(hold); }); });
  // No exception may leave the thread (it would end the service): one becomes the report's
  // failure, and the job ends in error.
  ls->thread = std::thread([raw] {
    try {
      raw->report = raw->sender->run(raw->stop);
    } catch (const std::exception& e) {
      raw->report.completed = false;
      raw->report.failure = std::string("the sender failed: ") + e.what();
    } catch (...) {
      raw->report.completed = false;
      raw->report.failure = "the sender failed (unknown exception)";
    }
    raw->done.store(true, std::memory_order_release);
  });
  std::cerr << "ncd serve: streaming job " << job_name_ << " to " << port_ << " at "
            << comms::describe(ls->line) << "\n";
  stream_ = std::move(ls);
}

void Service::link_hold(bool hold) {
  if (!cycle_ || cycle_->finished()) return;
  if (hold && state_ == State::Running) {
    std::cerr << "ncd serve: the link holds: bringing the motion to a stop\n";
    cycle_->hold();
    state_ = State::Holding;
    held_by_link_ = true;
  } else if (!hold && held_by_link_ && state_ == State::Holding) {
    std::cerr << "ncd serve: the link is free again: resuming the motion\n";
    cycle_->resume();
    state_ = State::Running;
    held_by_link_ = false;
  }
}

void Service::await_stream() {
  if (!stream_->done.load(std::memory_order_acquire)) {
    timer_.expires_after(std::chrono::milliseconds(20));
    timer_.async_wait([this](const boost::system::error_code& ec) {
      if (!ec) await_stream();
    });
    return;
  }
  stream_->thread.join();
  const comms::SenderReport& r = stream_->report;
  state_ = final_state_;
  if (!r.completed && state_ != State::Error) {
    state_ = State::Error;
    error_ = "the transfer to " + port_ +
             " did not complete: " + (r.stopped ? std::string("stopped") : r.failure);
  }
  std::cerr << "ncd serve: sent " << r.blocks << " blocks (" << r.bytes_written << " bytes) to "
            << port_ << " in " << r.duration_s << " s, " << 100.0 * r.link_use
            << " % of the line; sha256 " << r.program_sha256 << "\n";
  end_job();
}

json Service::stream_status() const {
  if (!stream_) return json();
  json s{{"port", port_},
         {"settings", comms::describe(stream_->line)},
         {"blocks_encoded", stream_->blocks_encoded.load()},
         {"chars_encoded", stream_->chars_encoded.load()},
         {"blocks_waiting", stream_->blocks.waiting()},
         {"held_by_link", held_by_link_}};
  {
    std::lock_guard lock(stream_->mutex);
    s["last_event"] = stream_->last_event;
  }
  if (stream_->done.load(std::memory_order_acquire)) {
    const comms::SenderReport& r = stream_->report;
    s["completed"] = r.completed;
    s["failure"] = r.failure;
    s["blocks_sent"] = r.blocks;
    s["bytes_written"] = r.bytes_written;
    s["link_use"] = r.link_use;
    s["xoff_count"] = r.xoff_count;
    s["xoff_timeouts"] = r.xoff_timeouts;
    s["reconnects"] = r.reconnects;
    s["blocks_resent"] = r.blocks_resent;
    s["program_sha256"] = r.program_sha256;
  }
  return s;
}

json Service::handle(const json& req) {
  const std::string cmd = req["cmd"];
  // Every key of a request is known, or the request is refused: a typo is never ignored.
  const auto keys_for = [](const std::string& c) -> std::vector<std::string> {
    if (c == "submit") return {"job", "port", "setpoints"};
    if (c == "override") return {"percent"};
    return {};
  };
  const std::vector<std::string> extra = keys_for(cmd);
  for (const auto& [key, value] : req.items()) {
    if (key == "cmd" || key == "token") continue;
    if (std::find(extra.begin(), extra.end(), key) == extra.end()) {
      std::string known = "\"cmd\"";
      for (const std::string& k : extra) known += ", \"" + k + "\"";
      throw InputError("unknown key \"" + key + "\" in a \"" + cmd + "\" request; it takes " +
                       known + " (and \"token\" when the service has one)");
    }
  }
  if (cmd == "submit") return submit(req);
  if (cmd == "start") return start();
  if (cmd == "status") return status();
  if (cmd == "hold") {
    require_active("hold");
    if (state_ != State::Holding) held_time_left_s_ = time_left_s();
    cycle_->hold();
    state_ = State::Holding;
  } else if (cmd == "resume") {
    require_active("resume");
    cycle_->resume();
    state_ = State::Running;
    held_time_left_s_.reset();
  } else if (cmd == "stop") {
    require_active("stop");
    stop_why_ = "stop requested by a client";
    cycle_->stop();
  } else if (cmd == "override") {
    require_active("override");
    const double pct = number(req, "percent");
    if (!(pct >= 0.0 && pct <= 200.0)) {
      throw InputError("override: \"percent\" = " + std::to_string(pct) + " is outside 0..200 %");
    }
    cycle_->set_override(pct / 100.0);
    override_percent_ = pct;
  } else {
    throw InputError("unknown command \"" + cmd +
                     "\"; commands: submit, start, hold, resume, stop, override, status, "
                     "subscribe");
  }
  return {{"ok", true}, {"state", name(state_)}};
}

// The time the job still needs: what is left of the path at the mean feed of the time spent
// moving so far (a hold adds neither time nor path, so the estimate does not grow while
// held); frozen at its value when the hold was asked for. None until the tool has moved.
std::optional<double> Service::time_left_s() const {
  if (state_ == State::Holding && held_time_left_s_) return held_time_left_s_;
  if (!cycle_) return std::nullopt;
  const motion::CycleStatus c = cycle_->status();
  if (!(moving_s_ > 0.0) || !(c.s_mm > 0.0)) return std::nullopt;
  const double mean_mm_per_s = c.s_mm / moving_s_;
  return std::max(0.0, cycle_->length_mm() - c.s_mm) / mean_mm_per_s;
}

json Service::stop_report() const {
  json r{{"why", stop_why_.empty() ? "stopped" : stop_why_},
         {"position", {last_.p.x(), last_.p.y(), last_.p.z()}},
         {"s_mm", last_.s_mm},
         {"length_mm", cycle_ ? cycle_->length_mm() : 0.0},
         {"line", json()}};
  if (cycle_ && path_) {
    const std::size_t seg = cycle_->job().walker().segment();
    if (seg < path_->segments.size() && path_->segments[seg].source_line > 0) {
      r["line"] = path_->segments[seg].source_line;
    }
  }
  return r;
}

json Service::status() {
  json s;
  s["ok"] = true;
  s["state"] = name(state_);
  s["job"] = job_name_.empty() ? json() : json(job_name_);
  double length = 0.0;
  if (cycle_) {
    const motion::CycleStatus c = cycle_->status();
    length = cycle_->length_mm();
    // Before the first period the cycle has published nothing: the path's start.
    if (c.periods == 0) {
      s["position"] = {start_mm_.x(), start_mm_.y(), start_mm_.z()};
    } else {
      s["position"] = {c.x_mm, c.y_mm, c.z_mm};
    }
    s["feed_mm_per_min"] = c.v_mm_per_s * 60.0;
    s["progress"] = length > 0.0 ? c.s_mm / length : 1.0;
    json left;  // null until the job has moved
    if (state_ == State::Done || state_ == State::Stopped || state_ == State::Streaming) {
      left = 0.0;
    } else if (const auto t = time_left_s()) {
      left = *t;
    }
    s["time_left_s"] = left;
    s["t_s"] = c.t_s;
    s["overruns"] = c.overruns;
    s["late_wakeups"] = c.late_wakeups;
  } else {
    s["position"] = json();
    s["feed_mm_per_min"] = 0.0;
    s["progress"] = 0.0;
    s["time_left_s"] = json();
    s["overruns"] = 0;
  }
  s["override_percent"] = override_percent_;
  s["setpoints"] = setpoints_;
  s["accel_max"] = accel_max_;
  s["jerk_max"] = jerk_max_;
  s["feed_max_mm_per_min"] = feed_max_ * 60.0;
  if (!error_.empty()) s["job_error"] = error_;
  if (state_ == State::Stopped) s["stopped"] = stop_report();
  if (interference_allowed_) s["interference_allowed"] = true;
  s["stream"] = stream_status();
  return s;
}

void Service::shutdown(std::function<void()> done) {
  if (state_ == State::Streaming) {
    std::cerr << "ncd serve: stopping the transfer (the journal keeps where it stopped)\n";
    on_idle_ = std::move(done);
    stream_->stop = true;
    return;
  }
  if (cycle_ && !cycle_->finished()) {
    std::cerr << "ncd serve: stopping the running job (a jerk-limited stop on the path)\n";
    stop_why_ = "the service was shut down (SIGTERM or SIGINT)";
    on_idle_ = std::move(done);
    cycle_->stop();
    return;
  }
  io_.post(std::move(done));
}

}  // namespace ncd::app
