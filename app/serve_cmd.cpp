// `ncd serve`: the service next to a machine. One io_context runs the control socket, the
// job state machine and signal handling; each running job has its cycle thread. SIGTERM or
// SIGINT brings any motion to a jerk-limited stop, ends a streamed job safely (the retract, M5,
// M9 and the program end reach the controller: docs/service.md, "Ending early") and exits 0;
// a second signal gives a transfer still under way up.
#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>
#include <csignal>
#include <functional>
#include <iostream>
#include <memory>

#include "api/control_server.hpp"
#include "api/event_feed.hpp"
#include "api/intake.hpp"
#include "api/mqtt_bridge.hpp"
#include "api/web_server.hpp"
#include "app/commands.hpp"
#include "core/input_file.hpp"

namespace ncd::app {
namespace {

struct ServeArgs {
  std::string config, listen;
};

int run_serve(const ServeArgs& a) {
  // One parse: the service's keys, the dashboard's [http], the fleet's [mqtt].
  api::ServiceConfig cfg;
  if (!a.config.empty()) cfg = api::load_service_config(a.config);
  if (!a.listen.empty()) cfg.listen = a.listen;
  boost::asio::io_context io;
  // Registered before the socket exists, so a signal sent as soon as it appears is queued for
  // the handler below, never met by the default action (which would skip the safe ending).
  boost::asio::signal_set signals(io, SIGINT, SIGTERM);
  api::Intake service(io, cfg);
  comms::ServerOptions options;
  options.token = cfg.token;
  comms::ListenAddress address = comms::ListenAddress::parse(cfg.listen);
  comms::ControlServer server(io, address, service, options);
  if (address.kind == comms::ListenAddress::Kind::Tcp) address.port = server.port();
  std::cerr << "ncd serve: listening on " << address.to_string()
            << " (machine: " << cfg.machine.source
            << ", clock: " << (cfg.clock == motion::ClockKind::Wall ? "wall" : "simulated") << ")"
            << std::endl;
  std::unique_ptr<api::WebServer> web;
  if (cfg.http.listen) {
    web = std::make_unique<api::WebServer>(io, cfg.http, service, cfg.token, cfg.machine.program);
    std::cerr << "ncd serve: dashboard on " << web->url() << std::endl;
  }
  std::unique_ptr<api::MqttBridge> bridge;
  if (cfg.mqtt) {
    // The machine's page, for the cell page's link (docs/fleet-mqtt.md, "Topics").
    if (cfg.mqtt->page_url.empty() && web) cfg.mqtt->page_url = api::reachable_page_url(web->url());
    bridge = std::make_unique<api::MqttBridge>(
        io, *cfg.mqtt, [&service] { return service.status(); },
        [&service](const nlohmann::json& request) { return service.handle(request); }, cfg.token);
    bridge->start();
  }
  // The service's events to the observers, drained on this io_context (api/event_feed.hpp).
  std::unique_ptr<api::EventFeed> feed;
  if (bridge || web) {
    feed = std::make_unique<api::EventFeed>(io, service.subscribe(api::EventFeed::kCapacity));
    if (bridge) {
      api::MqttBridge& b = *bridge;
      feed->add_sink([&b](const nlohmann::json& event) { b.push_event(event); });
    }
    if (web) {
      api::WebServer& w = *web;
      feed->add_sink([&w](const nlohmann::json& event) { w.push_event(event); });
    }
    feed->start();
  }
  // The first signal ends any job safely (its ending reaches the controller) and then the
  // service; a second one gives a transfer still under way up.
  std::function<void(const boost::system::error_code&, int)> on_signal;
  bool shutting_down = false;
  on_signal = [&](const boost::system::error_code& ec, int signal) {
    if (ec) return;
    const char* name = signal == SIGTERM ? "SIGTERM" : "SIGINT";
    if (shutting_down) {
      std::cerr << "ncd serve: " << name << " again: giving the transfer up" << std::endl;
      service.abort_transfer();
      return;
    }
    shutting_down = true;
    std::cerr << "ncd serve: " << name
              << ", shutting down (a job is ended safely first; a second signal gives its "
                 "transfer up)"
              << std::endl;
    signals.async_wait(on_signal);
    service.shutdown([&] {
      signals.cancel();
      if (feed) feed->close();  // hands the job's last events on
      server.close();
      if (web) web->close();
      io.stop();
    });
  };
  signals.async_wait(on_signal);
  // An exception out of a handler must not end the service: log it and go on serving (the
  // handlers of the job state machine catch their own and put the job in error).
  for (;;) {
    try {
      io.run();
      break;
    } catch (const std::exception& e) {
      std::cerr << "ncd serve: internal error (the service goes on): " << e.what() << std::endl;
    }
  }
  std::cerr << "ncd serve: stopped" << std::endl;
  return 0;
}

}  // namespace

void register_serve(CLI::App& app, Runner& run) {
  auto a = std::make_shared<ServeArgs>();
  CLI::App* c = app.add_subcommand("serve",
                                   "Run as a service: newline-delimited JSON requests on a control "
                                   "socket (see docs/cmd-serve.md). "
                                   "Runs until SIGTERM or SIGINT, which stop any motion cleanly.");
  c->add_option("--config", a->config,
                "service config (TOML): listen, token, machine, clock, realtime, [live_limits], "
                "[http] (the web dashboard), [mqtt] (the fleet's broker); see "
                "config/serve.example.toml");
  c->add_option(
      "--listen", a->listen,
      "tcp:HOST:PORT or unix:PATH (overrides the config; default unix:DIR/ncd.sock, DIR = "
      "$RUNTIME_DIRECTORY, else $XDG_RUNTIME_DIR, else /tmp)");
  c->callback([a, &run] { run = [a] { return run_serve(*a); }; });
}

}  // namespace ncd::app
