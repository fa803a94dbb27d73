// The [http] table of the serve config (http_config.hpp). Every value is checked here, before
// the server binds: a wrong key, type or range is an InputError naming the key, the value, the
// limit and a way out.
#include "api/http_config.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

#include "api/control_server.hpp"
#include "core/error.hpp"

namespace ncd::api {

HttpConfig parse_http_config(const toml::value& table, const std::string& where) {
  HttpConfig h;
  if (!table.is_table()) {
    throw InputError(where + " = " + toml::format(table) +
                     " must be a table, such as [http] listen = \"tcp:127.0.0.1:8080\"");
  }
  for (const auto& entry : table.as_table()) {
    const std::string& key = entry.first;
    const auto& v = entry.second;  // a plain reference: clang 14 cannot capture a binding
    const std::string at = where + "." + key;
    const auto text = [&]() -> std::string {
      if (!v.is_string() || v.as_string().str.empty()) {
        throw InputError(at + " = " + toml::format(v) +
                         " must be a non-empty string; quote it, or remove the key");
      }
      return v.as_string().str;
    };
    if (key == "listen") {
      const std::string listen = text();
      comms::ListenAddress address;
      try {
        address = comms::ListenAddress::parse(listen);
      } catch (const InputError& e) {
        throw InputError(at + ": " + e.what());
      }
      if (address.kind != comms::ListenAddress::Kind::Tcp) {
        throw InputError(at + " = \"" + listen +
                         "\": the dashboard listens on TCP only; use tcp:127.0.0.1:PORT");
      }
      h.listen = listen;
    } else if (key == "certificate") {
      h.certificate = text();
    } else if (key == "key") {
      h.key = text();
    } else if (key == "assets") {
      h.assets = text();
    } else if (key == "status_hz") {
      const double hz = v.is_floating()  ? v.as_floating()
                        : v.is_integer() ? static_cast<double>(v.as_integer())
                                         : std::nan("");
      if (!(hz >= HttpLimits::kMinStatusHz && hz <= HttpLimits::kMaxStatusHz)) {
        throw InputError(at + " = " + toml::format(v) +
                         " is out of range: status snapshots per second, at least " +
                         nlohmann::json(HttpLimits::kMinStatusHz).dump() + " and at most " +
                         nlohmann::json(HttpLimits::kMaxStatusHz).dump() +
                         "; give one in that range, or remove the key for 10");
      }
      h.status_hz = hz;
    } else {
      throw InputError("unknown key " + at +
                       "; [http] takes listen, certificate, key, assets, status_hz");
    }
  }
  if (h.certificate.empty() != h.key.empty()) {
    throw InputError(where +
                     " has only one of certificate and key; TLS needs both (PEM files), plain "
                     "HTTP neither");
  }
  if ((!h.certificate.empty() || !h.assets.empty()) && !h.listen) {
    throw InputError(where + " has no listen; add listen = \"tcp:127.0.0.1:PORT\"");
  }
  return h;
}

}  // namespace ncd::api
