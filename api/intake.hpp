// `ncd serve`'s JSON mapping: control requests to the service library's commands
// (service/service.hpp) and its status to JSON. The job lifecycle and the live pipeline are the
// library's; this file owns the request shapes, the checks a request's job passes before any
// motion (the same as `ncd replay`'s) and the timer that runs the library's loop on the
// io_context.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/control_server.hpp"
#include "api/service_config.hpp"
#include "core/geometry.hpp"
#include "geometry/path.hpp"
#include "link/dnc_sender.hpp"
#include "service/service.hpp"

namespace ncd::api {

// Where a job starts (docs/service.md, "Where a job starts"). A job that streams to a controller
// that reports its position (grbl: `?` answered with `<Idle|MPos:…|WCO:…>`, or WPos) starts
// where the controller stands, in the coordinates of the blocks ncd sends (its work
// coordinates); else at the request's "start_mm"; else at the machine file's [program]
// start_mm; else nowhere known, and a program whose first feed move comes from an unknown
// position is refused (its rapids position the machine from wherever it stands).
struct JobStart {
  std::optional<Vec3> at_mm;  // machine mm, the frame of the path and the blocks; none: unknown
  std::string from;           // "controller", "request", "machine file", or "" when unknown
  std::string note;     // why the controller's position was not used, or that it won the request's
  bool applies = true;  // false for a chamfer made from parameters: it starts at its clearance
};
// The controller's position as a start, asked with `?` alone (comms::probe_grbl): only an Idle
// grbl that did not reset on the port's opening and reports its work position.
struct ControllerPosition {
  std::optional<Vec3> at_mm;
  std::string why_not;  // when at_mm is none
};
// The probe waits this long for a banner before asking, then up to the settle time for an
// answer (grbl answers `?` within a few ms; an Arduino that resets on open says its banner).
inline constexpr double kProbeBannerWaitS = 0.25;
inline constexpr double kProbeSettleS = 2.0;
// Positions within this of each other, mm, are the same (grbl reports 3 decimals).
inline constexpr double kSamePositionMm = 0.002;
ControllerPosition controller_position(const comms::SenderSettings& settings);
JobStart job_start(const nlohmann::json& request, const ServiceConfig& config,
                   const std::string& port);
std::string position_text(const Vec3& at_mm);  // "[1.000, 2.000, 3.000]"

// A submit request's job (docs/service.md, "Jobs"): checked as `ncd replay` checks a run (the
// chamfer's checks and tool, the envelope, the size of the run, the port) and made into the
// library's JobSpec: the whole program `ncd replay` walks for the same file and machine
// (service/whole_run.hpp), or the path alone for a restart. Throws InputError naming the key.
struct SubmittedJob {
  service::JobSpec spec;
  std::string port;     // the DNC port; empty: no streaming
  std::string warning;  // a failed chamfer run anyway ("allow_interference"); empty otherwise
  JobStart start;       // where the job starts and why
  // A part's job: the program `ncd chamfer --part` writes for it, and the name it goes by.
  std::string program_text;
  std::string program_name;
};
SubmittedJob submitted_job(const nlohmann::json& request, const ServiceConfig& config);

// What the dashboard draws and lists of a job as soon as it is accepted (docs/web-dashboard.md,
// "The preview" and "The listing"), from whatever submitted it (the socket, MQTT, the page, a
// chamfer made from parameters): the path the job walks as polylines for the page
// (path_preview), and the program's text when the job is an NC program (G-code), one string a
// line, at most kMaxListingLines lines and kMaxListingBytes bytes (else "listing_truncated").
inline constexpr std::size_t kMaxListingLines = 50000;
inline constexpr std::size_t kMaxListingBytes = std::size_t{4} << 20;
nlohmann::json path_preview(const toolpath::Path& path);
// `text`: the program made in memory (a part's), listed under the name `file`.
nlohmann::json program_view(const std::string& job, const toolpath::Path& path,
                            const std::string& file, const std::string& text = "");

// The one request handler of `ncd serve`: the control socket, the web dashboard and MQTT all
// hand their requests to handle() and read status() (it was app::Service, beside the library's
// service::Service).
class Intake : public comms::ControlHandler {
 public:
  Intake(boost::asio::io_context& io, const ServiceConfig& config);
  ~Intake() override;

  nlohmann::json handle(const nlohmann::json& request) override;
  nlohmann::json status() override;
  std::shared_ptr<const nlohmann::json> program_view() override { return program_view_; }
  // SIGTERM/SIGINT: bring any motion to a jerk-limited stop, end the job safely (the ending
  // reaches the controller first), then call done (on the io_context).
  void shutdown(std::function<void()> done);
  // A second signal during the shutdown: give the transfer up (the ending is not sent; the
  // job's error says what to do at the machine).
  void abort_transfer();
  // A new observer's event feed (service::Service::subscribe; api/event_feed.hpp drains it).
  std::shared_ptr<service::Subscription> subscribe(std::size_t capacity) {
    return core_.subscribe(capacity);
  }

 private:
  nlohmann::json submit(const nlohmann::json& req);
  void run_loop();                 // service::Service::poll() on a timer while a job is under way
  void check_still_there() const;  // start: the controller is where the job was planned from

  boost::asio::io_context& io_;
  ServiceConfig config_;
  service::Service core_;
  boost::asio::steady_timer timer_;
  bool loop_armed_ = false;
  std::string port_;  // the submitted job's DNC port; empty: no streaming
  // The controller's position the submitted job starts from; checked again at start.
  std::optional<Vec3> controller_start_mm_;
  std::function<void()> on_idle_;                       // shutdown's continuation
  std::shared_ptr<const nlohmann::json> program_view_;  // the submitted job's (program_view)
};

// The status snapshot as the socket's JSON (field names with units; docs/cmd-serve.md).
nlohmann::json to_json(const service::Status& status);
// How a streamed job that ended early left the machine (docs/service.md, "Ending early").
nlohmann::json to_json(const service::EndingStatus& ending);
// One observer event as JSON (field names with units).
nlohmann::json to_json(const service::Event& event);

}  // namespace ncd::api
