// The [mqtt] table of the serve config. Every value is checked here, before the bridge starts:
// a wrong key, type or range is an InputError naming the key, the value, the limit and a way
// out (docs/fleet-mqtt.md, "Configuration").
#include "api/mqtt_config.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string>

#include "core/error.hpp"

namespace ncd::api {
namespace {

const char* kMqttKeys =
    "broker, client_id, username, password, ca_file, cert_file, key_file, topic_root, "
    "status_hz, queue_bound, reconnect_min_s, reconnect_max_s, page_url";

std::string need_mqtt_string(const toml::value& v, const std::string& where) {
  if (!v.is_string()) {
    throw InputError(where + " must be a string, not " + toml::format(v) + "; quote it");
  }
  std::string s = v.as_string().str;
  if (s.empty()) throw InputError(where + " is empty; give a value or remove the key");
  return s;
}

double need_number(const toml::value& v, const std::string& where, double lo, double hi,
                   const char* unit) {
  double x = 0.0;
  if (v.is_floating()) {
    x = v.as_floating();
  } else if (v.is_integer()) {
    x = static_cast<double>(v.as_integer());
  } else {
    throw InputError(where + " must be a number (" + unit + "), not " + toml::format(v));
  }
  if (!std::isfinite(x) || x < lo || x > hi) {
    std::ostringstream s;
    s << where << " = " << toml::format(v) << " is outside [" << lo << ", " << hi << "] " << unit
      << "; give a value in that range";
    throw InputError(s.str());
  }
  return x;
}

// A TLS file (ca_file, cert_file, key_file) must be a file the service can read now: Paho would
// only say "code -1" at every connection attempt.
void check_readable(const std::optional<std::string>& path, const std::string& where) {
  if (!path) return;
  std::error_code ec;
  const bool directory = std::filesystem::is_directory(*path, ec);
  std::FILE* f = directory ? nullptr : std::fopen(path->c_str(), "rb");
  const std::string why = directory ? "a directory" : (f ? "" : std::strerror(errno));
  if (f) std::fclose(f);
  if (why.empty()) return;
  throw InputError(where + " = \"" + *path + "\" cannot be read (" + why +
                   "); give the path of a PEM file the service can read (relative paths are "
                   "from the folder ncd serve runs in)");
}

// A topic root: "a/b/c/", levels without the wildcards '+' and '#', none empty.
void check_topic_root(const std::string& root, const std::string& where) {
  if (root.back() != '/') {
    throw InputError(where + " = \"" + root +
                     "\" must end with '/' (the topics are ROOT + status, ROOT + cmd...); "
                     "write \"" +
                     root + "/\"");
  }
  if (root.find_first_of("+#") != std::string::npos) {
    throw InputError(where + " = \"" + root +
                     "\" has an MQTT wildcard ('+' or '#'), which a publisher cannot use; name "
                     "the cell and the machine, such as \"ncd/cell1/m1/\"");
  }
  if (root.front() == '/' || root.find("//") != std::string::npos) {
    throw InputError(where + " = \"" + root +
                     "\" has an empty topic level; write it as \"ncd/<cell>/<machine>/\"");
  }
  if (root.size() > 1024) {
    throw InputError(where + " has " + std::to_string(root.size()) +
                     " bytes, the limit is 1024; use shorter cell and machine names");
  }
}

// This host's name as `hostname` prints it; "" if it cannot be read.
std::string host_name() {
  std::array<char, 256> name{};
  return ::gethostname(name.data(), name.size() - 1) == 0 ? std::string(name.data()) : "";
}

// A link a browser may follow: http:// or https://, printable, no spaces or quotes, bounded.
std::string need_page_url(const toml::value& v, const std::string& at) {
  const std::string url = need_mqtt_string(v, at);
  const bool scheme = url.rfind("http://", 0) == 0 || url.rfind("https://", 0) == 0;
  const bool printable = std::all_of(url.begin(), url.end(), [](char ch) {
    return ch > ' ' && ch < 0x7f && ch != '"' && ch != '\\' && ch != '<' && ch != '>';
  });
  if (!scheme || !printable || url.size() > kMaxPageUrlChars) {
    throw InputError(at + " = " + toml::format(v) + " is not a page address: http:// or https://" +
                     ", at most " + std::to_string(kMaxPageUrlChars) +
                     " characters, no spaces, quotes or <>; give the machine page's URL, such as "
                     "\"http://cell1-m1:8080/\", or remove the key for the [http] address");
  }
  return url;
}

}  // namespace

std::string default_topic_root() {
  std::string host = host_name();
  // A host name is one topic level: no '/', and no wildcard a publisher cannot use.
  for (char& ch : host) {
    if (ch == '/' || ch == '+' || ch == '#') ch = '-';
  }
  return "ncd/" + (host.empty() ? std::string("localhost") : host) + "/";
}

std::string reachable_page_url(const std::string& url) {
  for (const std::string wildcard : {"//0.0.0.0:", "//[::]:"}) {
    const std::size_t at = url.find(wildcard);
    if (at == std::string::npos) continue;
    std::string name = host_name();
    if (name.empty()) name = "localhost";
    return url.substr(0, at) + "//" + name + ":" + url.substr(at + wildcard.size());
  }
  return url;
}

MqttConfig parse_mqtt_config(const toml::value& table, const std::string& where) {
  if (!table.is_table()) {
    throw InputError(where + " must be a table ([mqtt] with keys " + std::string(kMqttKeys) + ")");
  }
  MqttConfig c;
  bool have_max = false;
  for (const auto& [key, v] : table.as_table()) {
    const std::string at = where + "." + key;
    if (key == "broker") {
      c.broker = need_mqtt_string(v, at);
    } else if (key == "client_id") {
      c.client_id = need_mqtt_string(v, at);
    } else if (key == "username") {
      c.username = need_mqtt_string(v, at);
    } else if (key == "password") {
      c.password = need_mqtt_string(v, at);
    } else if (key == "ca_file") {
      c.ca_file = need_mqtt_string(v, at);
    } else if (key == "cert_file") {
      c.cert_file = need_mqtt_string(v, at);
    } else if (key == "key_file") {
      c.key_file = need_mqtt_string(v, at);
    } else if (key == "topic_root") {
      c.topic_root = need_mqtt_string(v, at);
    } else if (key == "status_hz") {
      c.status_hz = need_number(v, at, kMinStatusHz, kMaxStatusHz, "Hz");
    } else if (key == "queue_bound") {
      if (!v.is_integer() || v.as_integer() < 1 ||
          v.as_integer() > static_cast<std::int64_t>(kMaxQueueBound)) {
        throw InputError(at + " = " + toml::format(v) +
                         " must be a whole number of events in [1, " +
                         std::to_string(kMaxQueueBound) + "]; give one in that range");
      }
      c.queue_bound = static_cast<std::size_t>(v.as_integer());
    } else if (key == "reconnect_min_s") {
      c.reconnect_min_s = need_number(v, at, kMinReconnectS, kMaxReconnectS, "s");
    } else if (key == "reconnect_max_s") {
      c.reconnect_max_s = need_number(v, at, kMinReconnectS, kMaxReconnectS, "s");
      have_max = true;
    } else if (key == "page_url") {
      c.page_url = need_page_url(v, at);
    } else {
      throw InputError("unknown key " + at + "; [mqtt] takes " + kMqttKeys);
    }
  }
  if (c.broker.empty()) {
    throw InputError(where +
                     " has no broker; add broker = \"tcp://HOST:1883\" (or ssl://HOST:8883 "
                     "with TLS), or remove [mqtt] to run without the broker");
  }
  const bool plain = c.broker.rfind("tcp://", 0) == 0 || c.broker.rfind("mqtt://", 0) == 0;
  if (!plain && !c.tls()) {
    throw InputError(where + ".broker = \"" + c.broker +
                     "\" starts with neither tcp://, mqtt://, ssl:// nor mqtts://; write it as "
                     "tcp://HOST:PORT");
  }
  if (c.broker.find_first_of(" \t\r\n") != std::string::npos) {
    throw InputError(where + ".broker = \"" + c.broker + "\" has white space; remove it");
  }
  if (c.topic_root.empty()) c.topic_root = default_topic_root();
  check_topic_root(c.topic_root, where + ".topic_root");
  if (c.client_id.empty()) {
    c.client_id = c.topic_root.substr(0, c.topic_root.size() - 1);
    for (char& ch : c.client_id) {
      if (ch == '/') ch = '-';
    }
  }
  if (c.client_id.size() > 65535) {
    throw InputError(where + ".client_id has " + std::to_string(c.client_id.size()) +
                     " bytes, MQTT's limit is 65535; use a shorter one");
  }
  if (c.username.has_value() != c.password.has_value()) {
    throw InputError(
        where + " has " +
        (c.username ? "a username without a password" : "a password without a username") +
        "; give both (the broker's password file) or neither");
  }
  if ((c.ca_file || c.cert_file || c.key_file) && !c.tls()) {
    throw InputError(where + " gives TLS files but broker = \"" + c.broker +
                     "\" is plain TCP; write the broker as ssl://HOST:8883, or remove the files");
  }
  if (c.cert_file.has_value() != c.key_file.has_value()) {
    throw InputError(
        where + " has " +
        (c.cert_file ? "a cert_file without a key_file" : "a key_file without a cert_file") +
        "; a client certificate needs both");
  }
  check_readable(c.ca_file, where + ".ca_file");
  check_readable(c.cert_file, where + ".cert_file");
  check_readable(c.key_file, where + ".key_file");
  if (have_max && c.reconnect_max_s < c.reconnect_min_s) {
    std::ostringstream s;
    s << where << ".reconnect_max_s = " << c.reconnect_max_s
      << " is below reconnect_min_s = " << c.reconnect_min_s << "; make it at least that";
    throw InputError(s.str());
  }
  c.reconnect_max_s = std::max(c.reconnect_max_s, c.reconnect_min_s);
  return c;
}

}  // namespace ncd::api
