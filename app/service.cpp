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
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <thread>
#include <toml.hpp>

#include "app/chamfer_report.hpp"
#include "comms/block_encoder.hpp"
#include "comms/live_blocks.hpp"
#include "comms/transfer_journal.hpp"
#include "core/error.hpp"
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
  for (const auto& [k, v] : j.items()) {
    if (std::find(std::begin(kKeys), std::end(kKeys), k) == std::end(kKeys)) {
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
    s.initial_segments = static_cast<int>(number(j, "initial_segments"));
  }
  toolpath::NgcOptions ngc;
  if (j.contains("feed")) ngc.feed_mm_per_min = number(j, "feed");
  if (j.contains("spindle")) ngc.spindle_rpm = number(j, "spindle");
  require_positive("feed", ngc.feed_mm_per_min);
  const toolpath::ChamferPath path = toolpath::generate_chamfer(s);
  if (!path.checks.local_ok || !path.checks.global_ok || !path.checks.rod_ok) {
    throw InputError(
        "the chamfer interferes with the part (see `ncd chamfer` with the same "
        "parameters); not submitted");
  }
  return toolpath::read_path_text(chamfer_json(path, ngc, nka_deg, 0.0).dump(), "chamfer job");
}

}  // namespace

ServiceConfig load_service_config(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot open service config " + path + " (--config)");
  std::stringstream text;
  text << in.rdbuf();
  toml::value root;
  try {
    std::istringstream s(text.str());
    root = toml::parse(s, path);
  } catch (const std::exception& e) {
    throw InputError("cannot read service config " + path + ": " + e.what());
  }
  ServiceConfig c;
  c.source = path;
  for (const auto& [key, v] : root.as_table()) {
    const std::string where = path + ": " + key;
    if (key == "listen" && v.is_string()) {
      c.listen = v.as_string();
    } else if (key == "token" && v.is_string()) {
      c.token = v.as_string().str;
    } else if (key == "machine" && v.is_string()) {
      c.machine_file = v.as_string();
    } else if (key == "clock" && v.is_string() &&
               (v.as_string() == "wall" || v.as_string() == "simulated")) {
      c.clock = v.as_string() == "wall" ? motion::ClockKind::Wall : motion::ClockKind::Simulated;
    } else if (key == "realtime" && v.is_boolean()) {
      c.realtime = v.as_boolean();
    } else if (key == "listen" || key == "token" || key == "machine" || key == "clock" ||
               key == "realtime") {
      throw InputError(where + " has the wrong type or value: " + toml::format(v) +
                       " (listen, token, machine: strings; clock: \"wall\" or \"simulated\"; "
                       "realtime: true or false)");
    } else {
      throw InputError("unknown key " + where +
                       "; the service config takes listen, token, machine, clock, realtime");
    }
  }
  if (!c.machine_file.empty()) c.machine = load_machine_config(c.machine_file);
  return c;
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
  j.limits = config_.machine.limits;
  j.cutting = config_.machine.cutting;
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
  std::unique_ptr<toolpath::Path> path;
  if (job.contains("path")) {
    if (!job["path"].is_string()) throw InputError("\"job\".\"path\" must be a file name");
    path = std::make_unique<toolpath::Path>(
        toolpath::read_path_file(job["path"], config_.machine.program));
    job_name_ = job["path"].get<std::string>();
  } else {
    path = std::make_unique<toolpath::Path>(chamfer_path(job));
    job_name_ = "chamfer";
  }
  // Build the job once now, so that a path the machine cannot run is refused at submit.
  (void)motion::Job(*path, job_config());
  port_ = config_.machine.link.line.device;
  if (req.contains("port")) {
    if (!req["port"].is_string()) {
      throw InputError("\"port\" must be a device name, or \"\" for no streaming");
    }
    port_ = req["port"];
  }
  setpoints_file_.clear();
  if (req.contains("setpoints")) {
    if (!req["setpoints"].is_string()) throw InputError("\"setpoints\" must be a file name");
    setpoints_file_ = req["setpoints"];
  }
  path_ = std::move(path);
  state_ = State::Ready;
  error_.clear();
  return {{"ok", true}, {"state", name(state_)}, {"job", job_name_}};
}

json Service::start() {
  if (state_ != State::Ready) {
    throw InputError(std::string("start: nothing to start (state ") + name(state_) +
                     "); submit a job first");
  }
  auto job = std::make_unique<motion::Job>(*path_, job_config());
  stream_.reset();
  held_by_link_ = false;
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

void Service::drain() {
  if (!cycle_) return;
  motion::Setpoint sp;
  while (cycle_->pop(sp)) {
    ++setpoints_;
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
  } else {
    state_ = State::Done;
  }
  try {
    sink_->commit();
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
  ls->thread = std::thread([raw] {
    raw->report = raw->sender->run(raw->stop);
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
  if (cmd == "submit") return submit(req);
  if (cmd == "start") return start();
  if (cmd == "status") return status();
  if (cmd == "hold") {
    require_active("hold");
    cycle_->hold();
    state_ = State::Holding;
  } else if (cmd == "resume") {
    require_active("resume");
    cycle_->resume();
    state_ = State::Running;
  } else if (cmd == "stop") {
    require_active("stop");
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

json Service::status() {
  json s;
  s["ok"] = true;
  s["state"] = name(state_);
  s["job"] = job_name_.empty() ? json() : json(job_name_);
  double length = 0.0;
  if (cycle_) {
    const motion::CycleStatus c = cycle_->status();
    length = cycle_->length_mm();
    s["position"] = {c.x_mm, c.y_mm, c.z_mm};
    s["feed_mm_per_min"] = c.v_mm_per_s * 60.0;
    s["progress"] = length > 0.0 ? c.s_mm / length : 1.0;
    const double avg = c.t_s > 0.0 ? c.s_mm / c.t_s : 0.0;  // mean feed so far, mm/s
    json left;  // null until the job has moved: the mean feed so far is the estimate
    if (state_ == State::Done) {
      left = 0.0;
    } else if (avg > 0.0) {
      left = (length - c.s_mm) / avg;
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
    on_idle_ = std::move(done);
    cycle_->stop();
    return;
  }
  io_.post(std::move(done));
}

}  // namespace ncd::app
