// The simulated controller's injected faults that run on a timer: XOFF storms, the end of a DC3
// hold, noise to the sender (drip: random bytes, ack: garbage lines). Count-triggered: accept().

#include "sim/sim_impl.hpp"

#include <cctype>

namespace ncd::comms {

namespace {

constexpr std::size_t kMaxOutQueue = 4096;  // beyond this, noise is not generated
constexpr double kReceivingS = 0.1;         // "while receiving": a byte within this long

}  // namespace

double SimController::Impl::uniform(double lo, double hi) {
  return std::uniform_real_distribution<>(lo, hi)(rng);
}

void SimController::Impl::faults(double t) {
  const SimFaults& f = cfg.faults;
  if (hold_until && t >= *hold_until) hold_until.reset();
  if (f.xoff_storm && port.is_open()) {
    if (storm_until && t >= *storm_until) {
      storm_until.reset();
      next_storm = t + uniform(0.05, 0.5);
    }
    if (!storm_until && t >= next_storm) {
      const bool receiving = log.bytes_received > 0 && t - log.last_byte_t_s < kReceivingS;
      if (receiving && !end_received && !alarmed) {
        storm_until = t + uniform(0.02, 0.3);
        ++log.xoff_storms;
      } else {
        next_storm = t + uniform(0.05, 0.5);
      }
    }
  }
  while (f.noise_bytes_per_s > 0.0 && open_count > 0 && t >= next_noise) {
    const std::size_t n = drip ? static_cast<std::size_t>(uniform(1.0, 5.0))
                               : static_cast<std::size_t>(uniform(4.0, 25.0));
    if (out.size() < kMaxOutQueue) {
      const std::string noise = drip ? noise_bytes(n) : noise_line(n);
      send(noise);
      log.noise_bytes_sent += noise.size();
    }
    // From the last due time, not from now: a late loop catches up instead of thinning out.
    next_noise = std::max(next_noise, t - 1.0) +
                 std::exponential_distribution<>(f.noise_bytes_per_s /
                                                 static_cast<double>(n + (drip ? 0 : 2)))(rng);
  }
}

// Random bytes that are none of DC1, DC3, NAK, SYN, LF, CR (7 bits on a 7-bit line).
std::string SimController::Impl::noise_bytes(std::size_t n) {
  std::string s;
  const int top = cfg.line.data_bits == 7 ? 0x7F : 0xFF;
  while (s.size() < n) {
    const char c = static_cast<char>(std::uniform_int_distribution<>(0, top)(rng));
    if (c != kXon && c != kXoff && c != kNak && c != kSyn && c != '\n' && c != '\r') s += c;
  }
  return s;
}

// A printable garbage line (with CR LF) that is no ok, error or ALARM line.
std::string SimController::Impl::noise_line(std::size_t n) {
  static constexpr char kChars[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 :<>|.,=[]-";
  for (;;) {
    std::string s;
    while (s.size() < n) {
      s += kChars[std::uniform_int_distribution<std::size_t>(0, sizeof kChars - 2)(rng)];
    }
    std::string lower = s;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (lower.rfind("ok", 0) != 0 && lower.rfind("error", 0) != 0 && lower.rfind("alarm", 0) != 0) {
      return s + "\r\n";
    }
  }
}

}  // namespace ncd::comms
