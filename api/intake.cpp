// `ncd serve`'s JSON mapping (service.hpp). A request's job is checked here as `ncd replay`
// checks a run (the chamfer's checks and tool, the envelope, the size of the run, the port),
// wrapped into the whole program `ncd replay` walks (service/whole_run.hpp, docs/whole-program.md),
// turned into a service::JobSpec and handed to the library, whose state machine is drawn at the
// top of service/service.cpp. The library's loop runs on a timer of the io_context: every 1 ms
// while the motion runs, every 20 ms while the controller is still receiving.
//
// A submitted job is {"path": FILE} in any format `ncd replay` reads, or a chamfer
// specification with the parameter names of `ncd chamfer` ("pipe_radius" or "pipe-radius", …).
// "setpoints": FILE records the job's setpoints in the replay CSV format; "port": DEV streams it
// live to the controller ("" turns the machine file's [link] device off); "restart_from": LINE
// (with "clearance_z_mm") restarts an NC program at a line (docs/service.md).
#include "api/intake.hpp"

#include <algorithm>
#include <chrono>
#include <iostream>
#include <utility>

#include "cam/part.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/json_input.hpp"
#include "core/number_text.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "gcode/path_io.hpp"
#include "service/chamfer_job.hpp"
#include "service/job_checks.hpp"
#include "service/link_options.hpp"
#include "service/part_job.hpp"
#include "service/restart.hpp"
#include "service/setpoint_file.hpp"
#include "service/whole_run.hpp"

namespace ncd::api {
namespace {

using nlohmann::json;

// A request's field as a number, with the key named in the error.
double number(const json& obj, const std::string& key) {
  if (!obj.contains(key)) throw InputError("\"" + key + "\" is missing");
  if (!obj[key].is_number()) throw InputError("\"" + key + "\" must be a number");
  return obj[key].get<double>();
}

// The chamfer job: the flags of `ncd chamfer` as JSON keys ('-' or '_').
service::ChamferJob chamfer_job(const json& spec) {
  json j;
  for (const auto& [k, v] : spec.items()) {
    std::string key = k;
    for (char& c : key) c = c == '-' ? '_' : c;
    j[key] = v;
  }
  static const char* kKeys[] = {"pipe_radius",      "drill_radius", "ball_radius", "width",
                                "tolerance",        "edge",         "side",        "rod_radius",
                                "non_knife_angle",  "no_avoid",     "feed",        "spindle",
                                "initial_segments", "safe_z"};
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
  service::ChamferJob job;
  toolpath::ChamferSpec& s = job.spec;
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
  if (j.contains("non_knife_angle")) {
    s.non_knife_angle_rad = deg_to_rad(number(j, "non_knife_angle"));
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
  if (j.contains("feed")) job.feed_mm_per_min = number(j, "feed");
  if (j.contains("spindle")) job.spindle_rpm = number(j, "spindle");
  if (j.contains("safe_z")) job.safe_z_mm = number(j, "safe_z");
  return job;
}

json vec(const Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

}  // namespace

ServiceConfig load_service_config(const std::string& path) {
  return parse_service_config(read_input_file(path, "service config, --config"), path);
}

Intake::Intake(boost::asio::io_context& io, const ServiceConfig& config)
    : io_(io),
      config_(config),
      core_([&config] {
        service::ServiceOptions o;
        o.clock = config.clock;
        o.realtime = config.realtime;
        o.log = [](const std::string& line) { std::cerr << "ncd serve: " << line << std::endl; };
        return o;
      }()),
      timer_(io) {}

Intake::~Intake() {
  timer_.cancel();
}

namespace {

// "job"."allow_interference": false when absent.
bool allow_interference_of(const json& job) {
  const auto allow = job.find("allow_interference");
  if (allow == job.end()) return false;
  if (!allow->is_boolean()) {
    throw InputError("\"job\".\"allow_interference\" must be true or false");
  }
  return allow->get<bool>();
}

// The job's path: a file ("path": an NC program or a path file) or a chamfer made from
// parameters.
struct JobPath {
  std::shared_ptr<toolpath::Path> path;
  std::string file;          // the path job's file; empty for a chamfer made from parameters
  std::string name;          // the job's name: the file, or "chamfer"
  std::string part_program;  // a part's job: the program `ncd chamfer --part` writes for it
};

// A part's job ({"part": FILE} or {"part_toml": TEXT}, docs/service.md "Jobs"): the program
// `ncd chamfer --part FILE --machine` writes for the service's machine (service/part_job.hpp).
JobPath part_job_path(const json& job, const ServiceConfig& config) {
  for (const auto& [key, value] : job.items()) {
    if (key != "part" && key != "part_toml") {
      throw InputError("unknown key \"job\".\"" + key +
                       "\" in a part job; it takes \"part\" (a part file) or \"part_toml\" "
                       "(its text)");
    }
  }
  if (job.contains("part") && job.contains("part_toml")) {
    throw InputError(
        "a part job takes \"part\" (a part file) or \"part_toml\" (its text), "
        "not both");
  }
  JobPath out;
  toolpath::Part part;
  if (job.contains("part")) {
    if (!job["part"].is_string()) throw InputError("\"job\".\"part\" must be a file name");
    out.name = job["part"].get<std::string>();
    part = toolpath::load_part(out.name);
  } else {
    if (!job["part_toml"].is_string()) {
      throw InputError("\"job\".\"part_toml\" must be the part file's TOML text");
    }
    out.name = "part_toml";
    part = toolpath::parse_part(job["part_toml"].get<std::string>(), out.name);
  }
  service::PartMachine machine;
  machine.machine = &config.machine;
  machine.name = config.machine.source;
  out.part_program = toolpath::part_program_text(service::plan_part_for(part, machine));
  return out;
}

JobPath job_path(const json& job, const ServiceConfig& config,
                 const toolpath::InterpretOptions& program) {
  JobPath out;
  if (job.contains("path")) {
    for (const auto& [key, value] : job.items()) {
      if (key != "path" && key != "allow_interference") {
        throw InputError("unknown key \"job\".\"" + key +
                         "\" in a path job; it takes \"path\" and \"allow_interference\"");
      }
    }
    if (!job["path"].is_string()) throw InputError("\"job\".\"path\" must be a file name");
    out.file = job["path"].get<std::string>();
    out.path = std::make_shared<toolpath::Path>(toolpath::read_path_file(out.file, program));
    out.name = out.file;
  } else if (job.contains("part") || job.contains("part_toml")) {
    out = part_job_path(job, config);
  } else {
    service::ChamferJob cj = chamfer_job(job);
    cj.point = config.machine.tool.programmed_point;  // as `ncd chamfer --machine` writes it
    out.path = std::make_shared<toolpath::Path>(service::chamfer_job_path(cj));
    out.name = "chamfer";
  }
  return out;
}

// "port": the machine file's device unless the request names one ("" for no streaming).
std::string port_of(const json& req, const ServiceConfig& config) {
  std::string port = config.machine.link.line.device;
  if (req.contains("port")) {
    if (!req["port"].is_string()) {
      throw InputError("\"port\" must be a device name, or \"\" for no streaming");
    }
    port = req["port"];
  }
  return port;
}

// "setpoints": the file to write them to, checked before the job is made; "" for none.
std::string setpoints_of(const json& req) {
  std::string setpoints;
  if (req.contains("setpoints")) {
    if (!req["setpoints"].is_string()) throw InputError("\"setpoints\" must be a file name");
    setpoints = req["setpoints"];
    check_output(setpoints, "\"setpoints\"");
  }
  return setpoints;
}

// "restart_from": the NC program of a path job restarted at a line, with the ending of a
// restarted job: straight up to the highest Z of the whole program, or the restart's
// clearance if that is higher.
void restart_at_line(const json& req, const json& job, const std::string& file,
                     const service::MachineConfig& machine, service::JobSpec& spec) {
  if (!job.contains("path")) {
    throw InputError(
        "\"restart_from\" needs a job {\"path\": FILE} of an NC program (a part's: "
        "write it with `ncd chamfer --part FILE -o PROGRAM` and submit that)");
  }
  const int line =
      static_cast<int>(json_integer(req["restart_from"], 1, 100000000, "\"restart_from\""));
  std::optional<double> clearance;
  if (req.contains("clearance_z_mm")) clearance = number(req, "clearance_z_mm");
  if (std::none_of(spec.path->segments.begin(), spec.path->segments.end(),
                   [](const auto& seg) { return seg.source_line > 0; })) {
    throw InputError(
        "\"restart_from\": the job's path has no program lines; only an NC "
        "program restarts from a line");
  }
  const std::string text = read_input_file(file, "\"job\".\"path\"");
  toolpath::Program program = toolpath::interpret_ngc(text, file, machine.program);
  const toolpath::Path planned = toolpath::to_path(program);
  if (!planned.segments.empty()) {
    toolpath::SafeRetract r = toolpath::program_retract(program, planned);
    if (clearance && *clearance > r.clearance_z_mm) {
      r.clearance_z_mm = *clearance;
      r.clearance_from = "the restart's \"clearance_z_mm\"";
    }
    spec.retract = r;
  }
  service::restart_job(spec, program, text, line, clearance);
}

// The link of a job that streams to `port`, from the machine file's [link] and [encoder].
service::LinkSpec link_spec(const ServiceConfig& config, const std::string& port) {
  service::LinkSpec link;
  const service::LinkConfig& lc = config.machine.link;
  link.encoder = config.machine.encoder;
  // The controller's dialect, as `ncd replay --blocks` and `ncd stream` apply it: the
  // encoder's framing, and every block checked by the sender before it is written.
  if (lc.dialect) comms::apply_dialect(link.encoder, *lc.dialect);
  link.sender.dialect = lc.dialect;
  link.sender.line = lc.line;
  link.sender.line.device = port;
  link.sender.max_queued_chars = lc.max_queued_chars;
  link.sender.rx_buffer_bytes = lc.rx_buffer_bytes;
  link.sender.xoff_timeout_s = lc.xoff_timeout_s;
  link.sender.reconnect_max_s = lc.reconnect_max_s;
  link.journal = lc.journal;
  return link;
}

// "start_mm": [x, y, z], machine mm; none when the request has no such key.
std::optional<Vec3> request_start(const json& req) {
  if (!req.contains("start_mm")) return std::nullopt;
  const json& v = req["start_mm"];
  if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
      !v[2].is_number()) {
    throw InputError(
        "\"start_mm\" must be three numbers, where the machine stands in mm: "
        "\"start_mm\": [0, 0, 50]");
  }
  const Vec3 at(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
  if (!at.allFinite() || at.cwiseAbs().maxCoeff() > 1e6) {
    throw InputError("\"start_mm\": " + v.dump() +
                     " must hold finite positions within ±1e6 mm (1 km)");
  }
  return at;
}

// The sender's settings for `port` from the machine file's [link], as the job's link will have.
comms::SenderSettings probe_settings(const ServiceConfig& config, const std::string& port) {
  comms::SenderSettings s = link_spec(config, port).sender;
  s.banner_wait_s = kProbeBannerWaitS;
  return s;
}

}  // namespace

std::string position_text(const Vec3& at) {
  return "[" + text::fixed(at.x(), 3) + ", " + text::fixed(at.y(), 3) + ", " +
         text::fixed(at.z(), 3) + "]";
}

ControllerPosition controller_position(const comms::SenderSettings& settings) {
  ControllerPosition out;
  if (settings.line.protocol != comms::Protocol::Ack) {
    out.why_not = "a drip-feed controller does not report its position";
    return out;
  }
  const comms::GrblProbe p = comms::probe_grbl(settings, kProbeSettleS);
  if (!p.spoke) {
    out.why_not = "the controller's position could not be read (" + p.failure + ")";
  } else if (p.banner) {
    out.why_not = "the controller reset when the port opened, so its position tells nothing";
  } else if (p.state != "Idle") {
    out.why_not = "the controller is " + p.state + ", not Idle, so its position is not a start";
  } else if (!p.position) {
    out.why_not =
        "the controller reported its machine position without the work offset (WCO), not the "
        "position in the coordinates ncd sends";
  } else {
    out.at_mm = Vec3((*p.position)[0], (*p.position)[1], (*p.position)[2]);
  }
  return out;
}

JobStart job_start(const json& req, const ServiceConfig& config, const std::string& port) {
  JobStart s;
  const std::optional<Vec3> requested = request_start(req);
  if (!port.empty()) {
    const ControllerPosition c = controller_position(probe_settings(config, port));
    if (c.at_mm) {
      s.at_mm = c.at_mm;
      s.from = "controller";
      if (requested && (*requested - *c.at_mm).cwiseAbs().maxCoeff() > kSamePositionMm) {
        s.note = "the controller reports " + position_text(*c.at_mm) +
                 ", not the request's \"start_mm\" " + position_text(*requested) +
                 ": the job starts where the controller is";
      }
      return s;
    }
    s.note = c.why_not;
  }
  if (requested) {
    s.at_mm = requested;
    s.from = "request";
  } else if (config.machine.program.start_machine_mm) {
    s.at_mm = config.machine.program.start_machine_mm;
    s.from = "machine file";
  }
  return s;
}

SubmittedJob submitted_job(const json& req, const ServiceConfig& config) {
  if (!req.contains("job") || !req["job"].is_object()) {
    throw InputError(
        "submit needs \"job\": {\"path\": FILE}, {\"part\": FILE} or a chamfer specification");
  }
  const json& job = req["job"];
  const bool allow_interference = allow_interference_of(job);
  SubmittedJob out;
  service::JobSpec& spec = out.spec;
  out.port = port_of(req, config);
  if (!out.port.empty()) service::require_serial_port(out.port, "\"port\"");
  // Where the job starts: the controller's position, else the request's, else the machine
  // file's [program] start_mm; every reading of the program below starts there.
  service::MachineConfig machine = config.machine;
  // A chamfer made from parameters starts at its clearance plane: only an NC program or a path
  // file (a part's job is an NC program) asks.
  const bool program = job.contains("path") || job.contains("part") || job.contains("part_toml");
  out.start = job_start(req, config, program ? out.port : std::string());
  out.start.applies = program;
  machine.program.start_machine_mm = out.start.at_mm;
  JobPath source = job_path(job, config, machine.program);
  std::optional<service::WholeRun> part_run;
  if (!source.part_program.empty()) {
    part_run = service::whole_ngc_run("ncd serve", source.name, source.part_program, machine);
    source.path = std::make_shared<toolpath::Path>(part_run->path);
    out.program_text = source.part_program;
    out.program_name = source.name;
  }
  std::shared_ptr<toolpath::Path> path = std::move(source.path);
  spec.name = source.name;
  const std::string setpoints = setpoints_of(req);
  // Before any motion, as `ncd replay` does: the chamfer's checks and tool, then the whole
  // program around the job (docs/whole-program.md), its envelope, the size of the run.
  const service::ChamferAcceptance chamfer =
      service::accept_chamfer(*path, machine, allow_interference, "\"allow_interference\": true");
  const bool restart = req.contains("restart_from");
  if (!restart) {
    service::WholeRun whole = part_run
                                  ? std::move(*part_run)
                                  : service::whole_run("ncd serve", source.file, *path, machine);
    path = std::make_shared<toolpath::Path>(std::move(whole.path));
    spec.program = std::make_shared<const toolpath::Program>(std::move(whole.program));
    spec.header = std::move(whole.header);
    spec.retract = std::move(whole.retract);
  }
  service::check_envelope(*path, machine);
  service::check_estimate(service::estimate_run(*path, machine), !setpoints.empty());
  spec.path = std::move(path);
  spec.motion.limits = machine.limits;
  spec.motion.cutting = machine.cutting;
  spec.rules = service::LiveLimitRules::from(machine.limits);
  spec.rules.feed = config.live_limits.feed;
  spec.rules.accel = config.live_limits.accel;
  spec.rules.jerk = config.live_limits.jerk;
  spec.rules.chord = config.live_limits.chord;
  spec.interference_allowed = chamfer.interference_allowed;
  if (restart) {
    restart_at_line(req, job, source.file, machine, spec);
  } else if (req.contains("clearance_z_mm")) {
    throw InputError("\"clearance_z_mm\" goes with \"restart_from\"");
  }
  if (!out.port.empty()) spec.link = link_spec(config, out.port);
  // As `ncd replay` writes them: with the rotary axis's column where the machine has one.
  spec.sink = std::make_unique<service::SetpointFileSink>(setpoints, machine.limits.rotary.axis);
  if (chamfer.interference_allowed) out.warning = chamfer.note;
  return out;
}

// A job planned from the controller's position starts only if the controller is still there:
// moved meanwhile (jogged, another program), the first move would not be the one planned.
void Intake::check_still_there() const {
  comms::SenderSettings settings = link_spec(config_, port_).sender;
  settings.banner_wait_s = kProbeBannerWaitS;
  const ControllerPosition now = controller_position(settings);
  const Vec3& planned = *controller_start_mm_;
  if (!now.at_mm) {
    throw InputError("start: the job was planned from the controller's position " +
                     position_text(planned) + ", which cannot be read again (" + now.why_not +
                     "): submit the job again");
  }
  if ((*now.at_mm - planned).cwiseAbs().maxCoeff() > kSamePositionMm) {
    throw InputError("start: the controller moved since the job was submitted, from " +
                     position_text(planned) + " to " + position_text(*now.at_mm) +
                     ": submit the job again to plan it from there");
  }
}

namespace {

// Where a path job starts, in the submit's reply ("start") and the log.
void log_start(const std::string& name, const JobStart& s, json& reply) {
  json start{{"position_mm", s.at_mm ? vec(*s.at_mm) : json()},
             {"from", s.from.empty() ? json() : json(s.from)}};
  if (!s.note.empty()) start["note"] = s.note;
  reply["start"] = start;
  std::cerr << "ncd serve: " << name << " starts at "
            << (s.at_mm ? position_text(*s.at_mm) + " (" + s.from + ")"
                        : std::string("an unknown position (its first move is a rapid)"))
            << (s.note.empty() ? "" : "; " + s.note) << std::endl;
}

}  // namespace

json Intake::submit(const json& req) {
  if (core_.busy()) throw InputError("submit: a job is running; stop it first");
  SubmittedJob job = submitted_job(req, config_);
  if (!job.warning.empty()) std::cerr << "ncd serve: " << job.warning << "\n";
  const std::string name = job.spec.name;
  const auto file = req["job"].find("path");
  auto view = std::make_shared<const json>(api::program_view(
      name, *job.spec.path, file != req["job"].end() ? file->get<std::string>() : job.program_name,
      job.program_text));
  core_.submit(std::move(job.spec));
  program_view_ = std::move(view);
  port_ = job.port;
  controller_start_mm_.reset();
  if (job.start.from == "controller") controller_start_mm_ = job.start.at_mm;
  json reply{{"ok", true}, {"state", service::to_string(core_.state())}, {"job", name}};
  if (job.start.applies) log_start(name, job.start, reply);
  if (!job.warning.empty()) reply["warning"] = job.warning;
  return reply;
}

void Intake::run_loop() {
  loop_armed_ = false;
  if (core_.poll()) {
    loop_armed_ = true;
    const auto every = core_.state() == service::State::Streaming ? std::chrono::milliseconds(20)
                                                                  : std::chrono::milliseconds(1);
    timer_.expires_after(every);
    timer_.async_wait([this](const boost::system::error_code& ec) {
      if (!ec) run_loop();
    });
    return;
  }
  if (on_idle_) io_.post(std::exchange(on_idle_, nullptr));
}

json Intake::handle(const json& req) {
  const std::string cmd = req["cmd"];
  // Every key of a request is known, or the request is refused: a typo is never ignored.
  const auto keys_for = [](const std::string& c) -> std::vector<std::string> {
    if (c == "submit") {
      return {"job", "port", "setpoints", "restart_from", "clearance_z_mm", "start_mm"};
    }
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
  if (cmd == "status") return status();
  if (cmd == "start") {
    // The port may have gone since submit.
    if (core_.state() == service::State::Ready && !port_.empty()) {
      service::require_serial_port(port_, "\"port\"");
      if (controller_start_mm_) check_still_there();
    }
    const std::string realtime = core_.start();
    if (!loop_armed_) run_loop();
    return {{"ok", true}, {"state", service::to_string(core_.state())}, {"realtime", realtime}};
  }
  if (cmd == "hold") {
    core_.hold(service::HoldHolder::Operator);
  } else if (cmd == "resume") {
    core_.resume(service::HoldHolder::Operator);
  } else if (cmd == "stop") {
    core_.stop("stop requested by a client");
    json reply{{"ok", true}, {"state", service::to_string(core_.state())}};
    const service::EndingStatus& e = core_.status().ending;
    if (e.state != service::EndingStatus::State::None) reply["ending"] = to_json(e);
    const std::string down = core_.link_down_note();
    if (!down.empty()) reply["warning"] = down;
    return reply;
  } else if (cmd == "override") {
    core_.set_override(number(req, "percent"));
  } else {
    throw InputError("unknown command \"" + cmd +
                     "\"; commands: submit, start, hold, resume, stop, override, status, "
                     "subscribe");
  }
  return {{"ok", true}, {"state", service::to_string(core_.state())}};
}

namespace {

// "stream" of the status: the link's encoder and sender, as they stand.
json stream_json(const service::LinkStatus& l, bool held_by_link) {
  json k{{"port", l.port},
         {"settings", l.settings},
         {"blocks_encoded", l.blocks_encoded},
         {"chars_encoded", l.chars_encoded},
         {"blocks_waiting", l.blocks_waiting},
         {"held_by_link", held_by_link},
         {"last_event", l.last_event}};
  // The sender's live counters (docs/service.md, "Status"); at the end they equal the report's.
  const comms::SenderCounts& c = l.counts;
  k["bytes_written"] = c.bytes_written;
  k["blocks_taken"] = c.blocks_taken;
  k["blocks_written"] = c.blocks_written;
  k["blocks_acked"] = c.blocks_acked >= 0 ? json(c.blocks_acked) : json();
  k["blocks_executed"] = c.blocks_executed >= 0 ? json(c.blocks_executed) : json();
  k["xoff_count"] = c.xoff_count;
  k["xoff_held"] = c.xoff_held;
  k["controller_buffer_bytes"] = c.buffer_bytes;
  k["controller_buffer_limit_bytes"] = c.buffer_limit_bytes;
  k["controller_buffer_basis"] =
      c.blocks_acked >= 0 ? "unanswered lines (character counting)" : "wire model";
  k["underruns"] = c.underruns;
  k["reconnects"] = c.reconnects;
  k["link_losses"] = c.link_losses;
  k["done"] = l.done;
  if (l.done) {
    const comms::SenderReport& r = l.report;
    k["completed"] = r.completed;
    k["failure"] = r.failure;
    k["blocks_sent"] = r.blocks;
    k["link_use"] = r.link_use;
    k["xoff_timeouts"] = r.xoff_timeouts;
    k["blocks_resent"] = r.blocks_resent;
    k["program_sha256"] = r.program_sha256;
  }
  return k;
}

json vec3(const std::array<double, 3>& v) {
  return {v[0], v[1], v[2]};
}

const char* spindle_name(toolpath::SpindleDir d) {
  switch (d) {
    case toolpath::SpindleDir::cw:
      return "cw";
    case toolpath::SpindleDir::ccw:
      return "ccw";
    case toolpath::SpindleDir::off:
      break;
  }
  return "off";
}

// The program's modal state (service/commanded_state.hpp), offsets in mm.
json modal_json(const service::CommandedModal& m) {
  return {{"units", m.units == toolpath::Units::inch ? "inch" : "mm"},
          {"work_offset_mm", vec(m.work_offset_mm)},
          {"tool_length_mm", vec(m.tool_length_mm)},
          {"tool_length_h", m.tool_length_h >= 0 ? json(m.tool_length_h) : json()},
          {"tool", m.tool},
          {"spindle", spindle_name(m.spindle)},
          {"spindle_rpm", m.spindle_rpm},
          {"coolant", {{"mist", m.mist}, {"flood", m.flood}}},
          {"line", m.line > 0 ? json(m.line) : json()}};
}

// The controller's last status report (ack), as it said it, with its age.
json controller_json(const comms::ControllerReport& r, double age_s) {
  const comms::GrblStatus& g = r.status;
  const auto opt = [](const auto& v) { return v ? json(*v) : json(); };
  return {{"state", g.state},
          {"mpos_mm", g.mpos ? vec3(*g.mpos) : json()},
          {"wpos_mm", g.wpos ? vec3(*g.wpos) : json()},
          {"wco_mm", g.wco ? vec3(*g.wco) : json()},
          {"work_mm", vec3(r.work_mm)},
          {"work_basis", g.wpos ? "WPos" : (r.wco_known ? "MPos less WCO" : "MPos (no WCO yet)")},
          {"free_blocks", opt(g.free_blocks)},
          {"free_bytes", opt(g.free_bytes)},
          {"line_number", opt(g.line_number)},
          {"feed_mm_per_min", opt(g.feed)},
          {"spindle_rpm", opt(g.spindle_rpm)},
          {"reports", r.reports},
          {"age_s", age_s}};
}

// The DRO (docs/web-dashboard.md, "The DRO"): the position in the program's units, as work
// coordinates (less the work offset and the tool length) and machine coordinates (the path's
// frame), with the tool length and the work offset apart; from the controller's report where
// the link gives one, else ncd's commanded position. Null before a job has run.
json dro_json(const service::Status& st) {
  std::optional<Vec3> at;
  std::optional<service::CommandedModal> modal;
  std::string source;
  if (st.controller_position_mm) {
    at = st.controller_position_mm;
    modal = st.progress_at_controller ? st.progress_at_controller->modal : std::nullopt;
    source = "controller";
  } else if (st.has_job_run) {
    at = st.position_mm;
    modal = st.commanded;
    source = "commanded";
  }
  if (!at) return json();
  const service::CommandedModal m = modal.value_or(service::CommandedModal{});
  const double k = 1.0 / toolpath::mm_per_unit(m.units);
  json d{{"units", m.units == toolpath::Units::inch ? "inch" : "mm"},
         {"source", source},
         {"work", vec((*at - m.work_offset_mm - m.tool_length_mm) * k)},
         {"machine", vec(*at * k)},
         {"tool_length", vec(m.tool_length_mm * k)},
         {"work_offset", vec(m.work_offset_mm * k)},
         {"modal_known", modal.has_value()}};
  if (source == "controller") d["age_s"] = st.controller_age_s;
  if (source == "commanded" && st.link) {
    d["note"] = "ncd's commanded position: it runs ahead of the controller";
  }
  return d;
}

json progress_json(const service::ControllerProgress& p) {
  return {{"source", p.source},
          {"block", p.block},
          {"number", p.number > 0 ? json(p.number) : json()},
          {"line", p.line > 0 ? json(p.line) : json()},
          {"blocks_behind", p.blocks_behind},
          {"seconds_behind", p.seconds_behind}};
}

}  // namespace

json to_json(const service::Status& st) {
  json s;
  s["ok"] = true;
  s["state"] = service::to_string(st.state);
  s["holder"] = service::to_string(st.holder);
  s["job"] = st.job.empty() ? json() : json(st.job);
  if (st.has_job_run) {
    s["position"] = vec(st.position_mm);
    s["feed_mm_per_min"] = st.feed_mm_per_min;
    s["progress"] = st.progress;
    s["time_left_s"] = st.time_left_s ? json(*st.time_left_s) : json();
    s["t_s"] = st.t_s;
    s["line"] = st.line > 0 ? json(st.line) : json();
    s["binding_limit"] = st.binding_limit.empty() ? json() : json(st.binding_limit);
    s["feed_limit_mm_per_min"] = st.binding_limit.empty() ? json() : json(st.feed_limit_mm_per_min);
    s["overruns"] = st.overruns;
    s["late_wakeups"] = st.late_wakeups;
  } else {
    s["position"] = json();
    s["feed_mm_per_min"] = 0.0;
    s["progress"] = 0.0;
    s["time_left_s"] = json();
    s["line"] = json();
    s["binding_limit"] = json();
    s["feed_limit_mm_per_min"] = json();
    s["overruns"] = 0;
  }
  // Non-empty bins only: [from_us, to_us) and the wake-ups that were that late.
  json bins = json::array();
  for (std::size_t g = 0; g < st.lateness_bins_ns.size(); ++g) {
    if (st.lateness_bins_ns[g] == 0) continue;
    const int coarse = static_cast<int>(g);
    bins.push_back({{"from_us", LogHistogram::coarse_from(coarse) * 1e-3},
                    {"to_us", LogHistogram::coarse_from(coarse + 1) * 1e-3},
                    {"count", st.lateness_bins_ns[g]}});
  }
  s["lateness_histogram"] = bins;
  s["override_percent"] = st.override_percent;
  s["setpoints"] = st.setpoints;
  s["accel_max"] = st.accel_max_mm_per_s2;
  s["jerk_max"] = st.jerk_max_mm_per_s3;
  s["feed_max_mm_per_min"] = st.feed_max_mm_per_min;
  s["live_limit_violations"] = {{"feed", st.violations.feed},
                                {"accel", st.violations.accel},
                                {"jerk", st.violations.jerk},
                                {"chord", st.violations.chord}};
  if (!st.error.empty()) s["job_error"] = st.error;
  if (st.stopped) {
    const service::StopReport& r = *st.stopped;
    s["stopped"] = {{"why", r.why},
                    {"position", vec(r.position_mm)},
                    {"s_mm", r.s_mm},
                    {"length_mm", r.length_mm},
                    {"line", r.line > 0 ? json(r.line) : json()}};
  }
  if (st.interference_allowed) s["interference_allowed"] = true;
  s["ending"] = st.ending.state == service::EndingStatus::State::None ? json() : to_json(st.ending);
  if (st.restart_line > 0) s["restart_from_line"] = st.restart_line;
  s["events_dropped"] = st.events_dropped;
  s["stream"] = st.link ? stream_json(*st.link, st.holder == service::HoldHolder::Link) : json();
  s["commanded_state"] = st.commanded ? modal_json(*st.commanded) : json();
  s["controller"] = st.controller ? controller_json(*st.controller, st.controller_age_s) : json();
  s["controller_progress"] =
      st.progress_at_controller ? progress_json(*st.progress_at_controller) : json();
  s["dro"] = dro_json(st);
  return s;
}

json to_json(const service::EndingStatus& e) {
  return {{"state", service::to_string(e.state)},
          {"how", e.how},
          {"blocks", e.blocks},
          {"note", e.note}};
}

json to_json(const service::Event& e) {
  json j{{"seq", e.seq},
         {"kind", service::to_string(e.kind)},
         {"state", service::to_string(e.state)},
         {"holder", service::to_string(e.holder)},
         {"job_t_s", e.job_t_s},
         {"time_unix_s", e.time_unix_s},
         {"text", std::string(e.message())}};
  if (e.kind == service::EventKind::Overrun) {
    j["overruns"] = e.count;
    j["late_wakeups"] = static_cast<std::int64_t>(e.value);
  }
  if (e.kind == service::EventKind::Override) {
    j["percent"] = e.value;
    j["previous_percent"] = e.limit;
  }
  if (e.kind == service::EventKind::Violation) {
    j["value"] = e.value;
    j["limit"] = e.limit;
  }
  return j;
}

json Intake::status() {
  return to_json(core_.status());
}

void Intake::shutdown(std::function<void()> done) {
  if (!core_.busy()) {
    io_.post(std::move(done));
    return;
  }
  on_idle_ = std::move(done);
  core_.shutdown("the service was shut down (SIGTERM or SIGINT)");
  if (!loop_armed_) run_loop();
}

void Intake::abort_transfer() {
  core_.abort_transfer("a second SIGTERM or SIGINT during the shutdown");
  if (!loop_armed_) run_loop();
}

}  // namespace ncd::api
