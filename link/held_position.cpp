// Whether a held position can be trusted: see held_position.hpp.
#include "link/held_position.hpp"

#include <algorithm>
#include <cmath>

namespace ncd::comms {
namespace {

using P3 = std::array<double, 3>;

double distance_mm(const P3& a, const P3& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

// Distance from p to the straight segment a–b.
double to_segment_mm(const P3& p, const P3& a, const P3& b) {
  const P3 d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  double u = len2 > 0.0
                 ? ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1] + (p[2] - a[2]) * d[2]) / len2
                 : 0.0;
  u = std::clamp(u, 0.0, 1.0);
  return distance_mm(p, {a[0] + u * d[0], a[1] + u * d[1], a[2] + u * d[2]});
}

}  // namespace

std::string held_position_doubt(const P3& pos_mm, const std::optional<P3>& last_end_mm,
                                const std::vector<HeldCandidate>& moves, double tol_mm) {
  for (const HeldCandidate& m : moves) {
    if (!m.geo.known) {
      const std::string_view text = m.text.substr(0, m.text.find_first_of("\r\n"));
      return "a block the controller may still hold moves in a way ncd cannot follow (" +
             std::string(text) + ")";
    }
  }
  if (last_end_mm && distance_mm(*last_end_mm, pos_mm) <= tol_mm) return {};
  for (const HeldCandidate& m : moves) {
    if (m.geo.motion && to_segment_mm(pos_mm, m.geo.from_mm, m.geo.to_mm) <= tol_mm) return {};
  }
  return "it lies on none of the moves the controller was sent and not known done, and not "
         "where the last move known done ended: the controller has reset or been moved since "
         "(a power-up counts from 0)";
}

}  // namespace ncd::comms
