// The [mqtt] table of the serve config (`ncd serve --config FILE.toml`): the broker, the
// credentials, TLS, the topic root and the bounds of the MQTT bridge. See docs/fleet-mqtt.md.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <toml.hpp>

namespace ncd::api {

struct MqttConfig {
  std::string broker;     // tcp://HOST:PORT, mqtt://, ssl:// or mqtts:// (TLS)
  std::string client_id;  // default: the topic root with '/' as '-' ("ncd-cell1-m1")
  std::optional<std::string> username, password;
  std::optional<std::string> ca_file, cert_file, key_file;  // TLS: PEM files
  std::string topic_root;          // "ncd/<cell>/<machine>/", ends with '/'; default ncd/<host>/
  double status_hz = 10.0;         // the status topic's rate
  std::size_t queue_bound = 1000;  // events buffered while the broker is away
  double reconnect_min_s = 0.5;    // the first reconnection delay, doubled up to
  double reconnect_max_s = 30.0;   // this one
  // The machine's own page, published in the online message for the cell page to link to:
  // http:// or https://; default (set by `ncd serve`) the [http] dashboard's address.
  std::string page_url;
  bool tls() const { return broker.rfind("ssl://", 0) == 0 || broker.rfind("mqtts://", 0) == 0; }
};

// The limits of the numbers above (docs/fleet-mqtt.md, "Bounds").
inline constexpr double kMinStatusHz = 0.1, kMaxStatusHz = 100.0;
inline constexpr std::size_t kMaxQueueBound = 100000;
inline constexpr double kMinReconnectS = 0.05, kMaxReconnectS = 3600.0;
inline constexpr std::size_t kMaxPageUrlChars = 2048;

// Reads the [mqtt] table (the service config's parser, api/service_config.cpp, hands it over);
// `where` names it in messages ("serve.toml: mqtt"). Throws
// InputError naming the key, the value, the limit and a way out.
MqttConfig parse_mqtt_config(const toml::value& table, const std::string& where);

// The topic root when [mqtt] names none: "ncd/<host name>/" (a '/', '+' or '#' in the name
// becomes '-'; "localhost" if the name cannot be read).
std::string default_topic_root();

// The dashboard's URL as another host reaches it: a wildcard listen address (0.0.0.0, ::) is
// replaced by this host's name ("http://0.0.0.0:8080/" → "http://cell1-m1:8080/").
std::string reachable_page_url(const std::string& url);

}  // namespace ncd::api
