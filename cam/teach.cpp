// Off-line teaching of a deburring path: paper 003 (Kim, Park, Lee) §3.2–3.3, with the
// conventions of docs/teach.md.
//
// Frame (§3.2). Three digitized points fix the frame the program is written in: P1 is the
// origin, P2 lies on +X, P3 in the XY plane.
//
//     e_x = (P2 − P1) / |P2 − P1|                     eqs. (14)–(16)
//     e_z = (P2 − P1) × (P3 − P1) / |…|               eqs. (5)–(13), the plane's unit normal
//     e_y = e_z × e_x                                 eqs. (17)–(18)
//     p'  = Rᵀ (p − P1),   R = [e_x e_y e_z]          eqs. (1)–(4)
//
// The paper reaches e_z through the plane equation a x + b y + c z + d = 0 solved by Cramer's
// rule (eqs. 5–12), which breaks down for a plane through the digitizer's origin (d = 0); the
// cross product is the same normal without that case. The frame is right-handed, and +Z is the
// side that (P2 − P1) × (P3 − P1) points to.
//
// Offset (§3.3, Fig. 8b, eqs. 19–20). The tool centre for a taught point P_k lies on the path's
// normal in the frame's XY plane, D/2 − l from P_k, on the stated side of the direction of
// travel; Z is kept. (Eq. 19 prints l for that distance, and eq. 20 "− P_k/y" for "+ P_k/y";
// the text and the paper's program say D/2 − l and the normal through P_k.) The paper's
// program lies to the LEFT of travel: its check values are only met with n = (−m, 1)/√(1 + m²)
// while x increases. The tangent at P_k comes from a quadratic through P_k and its neighbours:
//
//   paper parabola   y = a x² + b x + c through P_{k−1}, P_k, P_{k+1}; m = 2 a x_k + b, tangent
//                    ±(1, m) with the sign of the direction of travel in x (not of m). Used
//                    where the three x are strictly monotone and both chords lie within 60° of
//                    the X axis: there y(x) is a graph and the paper's numbers are kept exactly;
//   chord quadratic  everywhere else (vertical tangents, points doubling back in x): x(t) and
//                    y(t) quadratic through the three points at chord-length parameters
//                    t = 0, |P_k − P_{k−1}|, + |P_{k+1} − P_k|; tangent dp/dt at P_k.
//
//            P_{k−1} ●━━━━━━━━━● P_k ━━━━━━━━━● P_{k+1}       direction of travel ──►
//                              ┆
//                              ┆ D/2 − l, along the normal on the tool's side
//                              ○ tool centre (left: normal = tangent turned +90°)
//
// On a circle of radius ρ with steps h the parabola's direction is off by about
// tanθ · h²/(2ρ²) at chord angle θ (0.5° at 60° and h = ρ/10), which grows without bound as
// θ → 90°, while the chord quadratic's tangent at a middle point is exact on any circle (a
// positive blend of the two unit chords weighted by the opposite chord lengths: its normal is
// radial for any spacing). So the switch loses nothing but the paper's own error, and moves the
// normal by no more than that where it happens. The criterion looks at the fit's points only; a
// rigid motion of the part and the frame points together leaves every p', hence the program,
// unchanged.
//
// End points of an open path use the quadratic through the first (last) three points,
// evaluated at the end; a closed loop takes its neighbours across the join. Curvature always
// comes from the chord quadratic, (x'y'' − y'x'')/|p'|³, signed positive where the path turns
// left: the parabola's y'' = 2a is one constant over its three points, first-order wrong on
// unequal steps (24 % on a circle at 14° steps where the chord quadratic is within 1.5 %). Where
// the path bends towards the tool with a radius below D/2 − l the tool cuts deeper than l beside
// P_k (the paper asks for a tool diameter below the smallest radius of curvature, which is
// stricter); that radius is reported in the program, not refused.
//
// Program (§3.3). Straight G01 moves through every offset point, so that the tool passes
// through each one (the paper rejects approximating splines for the under- and over-cut they
// cause), in the paper's glued format "G01X28.728Y-6.595Z-0.765", truncated (--truncate, as
// the paper) or rounded to the stated decimals. Before the first point a rapid to the
// clearance plane above it; after the last a rapid back up. The program changes no tool (the
// paper's has none): it takes the length of the tool in the spindle with G43 H (--tool) before
// its first move, or, for a controller without a tool table, leaves it to the work offset.
#include "cam/teach.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <sstream>
#include <string_view>

#include "core/decimal.hpp"
#include "core/error.hpp"

namespace ncd::toolpath {
namespace {

using Vec2 = Eigen::Vector2d;

// Shortest decimal that reads back as v, in fixed notation ("47.45", "300", "-0.1").
std::string shortest(double v) {
  std::array<char, 400> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v, std::chars_format::fixed);
  return std::string(buf.data(), r.ptr);
}

// Numbers in messages and the header: 3 decimals, rounded.
std::string num(double v) {
  return format_fixed(v, 3, Rounding::Nearest);
}

// A coordinate as given but for digits beyond the 6th decimal ("47.45", not "47.450000").
std::string given(double v) {
  std::string s = format_fixed(v, 6, Rounding::Nearest);
  s.erase(s.find_last_not_of('0') + 1);
  if (s.back() == '.') s.pop_back();
  return s;
}

std::string triple(const Vec3& p) {
  return given(p.x()) + ", " + given(p.y()) + ", " + given(p.z());
}

// "point 4 (dp4, line 5)": 1-based, with what the source says about it.
std::string label(const std::vector<TaughtPoint>& points, std::size_t i) {
  const TaughtPoint& p = points[i];
  std::string about = p.name;
  if (p.line > 0) about += (about.empty() ? "line " : ", line ") + std::to_string(p.line);
  return "point " + std::to_string(i + 1) + (about.empty() ? "" : " (" + about + ")");
}

// Throws unless every coordinate is finite and within ±kMaxCoordinateMm.
void require_coordinates(const Vec3& p, const std::string& what) {
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(p[a]) || std::abs(p[a]) > TeachLimits::kMaxCoordinateMm) {
      throw InputError(what + " = (" + triple(p) + ") mm: coordinate " + std::string(1, "xyz"[a]) +
                       " must be a finite number within ±" +
                       shortest(TeachLimits::kMaxCoordinateMm) +
                       " mm; check the file and its units (mm)");
    }
  }
}

// f' and f'' at s = at of the quadratic through (s_i, f_i), from its Lagrange form.
std::array<double, 2> quadratic_derivatives(const std::array<double, 3>& s,
                                            const std::array<double, 3>& f, double at) {
  double d1 = 0.0, d2 = 0.0;
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3, k = (i + 2) % 3;
    const double denom = (s[i] - s[j]) * (s[i] - s[k]);
    d1 += f[i] * ((at - s[j]) + (at - s[k])) / denom;
    d2 += 2.0 * f[i] / denom;
  }
  return {d1, d2};
}

// The tangent at one of three consecutive points: direction of travel (not unit), the fit that
// gave it, and the signed curvature (of the chord quadratic, whichever fit gave the tangent).
struct Tangent {
  Vec2 direction;
  double curvature_per_mm = 0.0;
  TangentFit fit = TangentFit::PaperParabola;
};

// Whether the paper's parabola y(x) applies: x strictly monotone, chords within 60° of X.
bool paper_fit_applies(const std::array<Vec2, 3>& p) {
  const double max_slope = std::tan(deg_to_rad(TeachLimits::kPaperFitMaxChordAngleDeg));
  const Vec2 c1 = p[1] - p[0], c2 = p[2] - p[1];
  if (c1.x() == 0.0 || c2.x() == 0.0 || (c1.x() > 0.0) != (c2.x() > 0.0)) return false;
  return std::abs(c1.y()) <= max_slope * std::abs(c1.x()) &&
         std::abs(c2.y()) <= max_slope * std::abs(c2.x());
}

// The tangent at p[at] of the quadratic through p (see the top of this file).
Tangent fit_tangent(const std::array<Vec2, 3>& p, std::size_t at) {
  Tangent t;
  const double d1 = (p[1] - p[0]).norm(), d2 = (p[2] - p[1]).norm();
  const std::array<double, 3> s{0.0, d1, d1 + d2};
  const auto [xp, xpp] = quadratic_derivatives(s, {p[0].x(), p[1].x(), p[2].x()}, s[at]);
  const auto [yp, ypp] = quadratic_derivatives(s, {p[0].y(), p[1].y(), p[2].y()}, s[at]);
  t.direction = Vec2(xp, yp);
  const double speed = t.direction.norm();
  t.curvature_per_mm = (xp * ypp - yp * xpp) / (speed * speed * speed);
  t.fit = TangentFit::ChordQuadratic;
  if (paper_fit_applies(p)) {
    const double m = quadratic_derivatives({p[0].x(), p[1].x(), p[2].x()},
                                           {p[0].y(), p[1].y(), p[2].y()}, p[at].x())[0];
    t.direction = (p[2].x() > p[0].x() ? 1.0 : -1.0) * Vec2(1.0, m);
    t.fit = TangentFit::PaperParabola;
  }
  return t;
}

std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> out;
  for (std::size_t start = 0;;) {
    const std::size_t end = s.find(sep, start);
    out.push_back(trim(s.substr(start, end == std::string_view::npos ? end : end - start)));
    if (end == std::string_view::npos) return out;
    start = end + 1;
  }
}

std::vector<std::string_view> split_blank(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r')) ++i;
    const std::size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t' && s[i] != '\r') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

// Whether the whole token reads as a number of the decimal grammar (core/decimal.hpp), even
// one too large or too small to use: "1.5", "-2", "+3e1"; not "1.5mm", "+-10", "0x1p5", "".
bool parse_number(std::string_view tok, double& v) {
  const DecimalResult r = parse_decimal(tok);
  v = r.value;
  return r.error != DecimalError::Malformed;
}

// A coordinate from a token, or an InputError that names where, why and how to fix it.
double coordinate(std::string_view tok, char axis, const std::string& where) {
  const DecimalResult r = parse_decimal(tok);
  if (!r) {
    throw InputError(where + ": '" + std::string(tok) + "' (" + std::string(1, axis) + ") " +
                     decimal_error_text(r.error) + "; write plain decimal numbers in mm");
  }
  return r.value;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

}  // namespace

std::string to_string(TravelSide side) {
  return side == TravelSide::Left ? "left" : "right";
}

std::string format_fixed(double v, int decimals, Rounding rounding) {
  std::string s;
  if (rounding == Rounding::Nearest) {
    std::array<char, 400> buf{};
    const auto r =
        std::to_chars(buf.data(), buf.data() + buf.size(), v, std::chars_format::fixed, decimals);
    s.assign(buf.data(), r.ptr);
  } else {
    s = shortest(v);
    std::size_t point = s.find('.');
    if (point == std::string::npos) {
      point = s.size();
      s += '.';
    }
    s.resize(point + 1 + static_cast<std::size_t>(decimals), '0');
  }
  if (s.find_first_of("123456789") == std::string::npos && s.front() == '-') s.erase(0, 1);
  return s;
}

TeachFrame make_frame(const std::array<Vec3, 3>& p, const std::string& what) {
  for (std::size_t i = 0; i < 3; ++i) {
    require_coordinates(p[i], what + " P" + std::to_string(i + 1));
  }
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3;
    const double d = (p[j] - p[i]).norm();
    if (d < TeachLimits::kMinFrameSpacingMm) {
      throw InputError(what + ": P" + std::to_string(std::min(i, j) + 1) + " and P" +
                       std::to_string(std::max(i, j) + 1) + " are " + num(d) +
                       " mm apart, closer than " + shortest(TeachLimits::kMinFrameSpacingMm) +
                       " mm: they cannot fix a frame; digitize the frame points farther apart");
    }
  }
  const Vec3 a = p[1] - p[0], b = p[2] - p[0];
  const Vec3 normal = a.cross(b);
  const double sin_angle = normal.norm() / (a.norm() * b.norm());
  if (!(sin_angle >= std::sin(deg_to_rad(TeachLimits::kMinFrameAngleDeg)))) {
    const double angle_deg = rad_to_deg(std::atan2(normal.norm(), a.dot(b)));
    throw InputError(what +
                     ": the three frame points are collinear (angle P2-P1-P3 = " + num(angle_deg) +
                     " deg, must be between " + shortest(TeachLimits::kMinFrameAngleDeg) + " and " +
                     shortest(180.0 - TeachLimits::kMinFrameAngleDeg) +
                     " deg): they do not fix a plane; digitize P3 away from the line P1-P2");
  }
  TeachFrame f;
  f.points_mm = p;
  const Vec3 ex = a.normalized(), ez = normal.normalized();
  f.r.col(0) = ex;
  f.r.col(1) = ez.cross(ex);
  f.r.col(2) = ez;
  return f;
}

void validate(const TeachSpec& s) {
  require_positive("tool diameter D (--tool-diameter, mm)", s.tool_diameter_mm);
  if (!std::isfinite(s.depth_mm) || s.depth_mm < 0.0) {
    throw InputError("depth l (--depth, mm) = " + shortest(s.depth_mm) +
                     " is invalid: it must be a finite number of at least 0");
  }
  const double radius = 0.5 * s.tool_diameter_mm;
  if (s.depth_mm >= radius) {
    throw InputError("depth l (--depth) = " + shortest(s.depth_mm) +
                     " mm is not below the tool radius D/2 = " + shortest(radius) +
                     " mm: the tool centre would sit on or behind the taught edge; use a smaller "
                     "--depth or a larger --tool-diameter");
  }
}

void validate(const TeachProgramOptions& o) {
  require_positive("feed (--feed, mm/min)", o.feed_mm_per_min);
  require_positive("spindle speed (--spindle, rpm)", o.spindle_rpm);
  require_positive("clearance (--clearance, mm)", o.clearance_mm);
  if (o.decimals < TeachLimits::kMinDecimals || o.decimals > TeachLimits::kMaxDecimals) {
    throw InputError("decimals (--decimals) = " + std::to_string(o.decimals) +
                     " is out of range: give " + std::to_string(TeachLimits::kMinDecimals) +
                     " to " + std::to_string(TeachLimits::kMaxDecimals) +
                     " digits after the point (3 is the paper's 1 um)");
  }
  if (o.tool < 0 || o.tool > 99999) {
    throw InputError("tool number (--tool) = " + std::to_string(o.tool) +
                     " is out of range: give the tool table's entry of the tool in the spindle, "
                     "0 to 99999");
  }
}

TeachPath teach(const std::vector<TaughtPoint>& points, const TeachFrame& frame,
                const TeachSpec& spec) {
  validate(spec);
  const std::size_t n = points.size();
  if (n < TeachLimits::kMinPoints) {
    throw InputError("the path has " + std::to_string(n) + " point(s), fewer than the " +
                     std::to_string(TeachLimits::kMinPoints) +
                     " the tangent fit of eqs. (19)-(20) needs; digitize at least three points");
  }
  if (n > TeachLimits::kMaxPoints) {
    throw InputError("the path has " + std::to_string(n) + " points, more than " +
                     std::to_string(TeachLimits::kMaxPoints) + "; split it into several programs");
  }
  TeachPath out;
  out.spec = spec;
  out.frame = frame;
  out.offset_mm = 0.5 * spec.tool_diameter_mm - spec.depth_mm;
  std::vector<Vec3> q(n);
  for (std::size_t i = 0; i < n; ++i) {
    require_coordinates(points[i].p_mm, label(points, i));
    q[i] = frame.to_frame(points[i].p_mm);
  }
  const std::size_t joins = spec.closed ? n : n - 1;
  for (std::size_t i = 0; i < joins; ++i) {
    const std::size_t j = (i + 1) % n;
    const double d = (q[j] - q[i]).head<2>().norm();
    if (d < TeachLimits::kMinSpacingMm) {
      throw InputError(label(points, i) + " and " + label(points, j) + " are " + given(d) +
                       " mm apart in the frame's XY plane, closer than " +
                       shortest(TeachLimits::kMinSpacingMm) +
                       " mm: the direction of travel between them is undefined; remove one of "
                       "them" +
                       (spec.closed && j == 0 ? " (--closed already joins the last point to the "
                                                "first)"
                                              : ""));
    }
  }
  const double side = spec.side == TravelSide::Left ? 1.0 : -1.0;
  out.min_tool_side_radius_mm = kInf;
  out.points.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    // Neighbours across the join of a loop; the first or last three points at an open end.
    std::array<std::size_t, 3> idx{(k + n - 1) % n, k, (k + 1) % n};
    std::size_t at = 1;
    if (!spec.closed && (k == 0 || k == n - 1)) {
      const std::size_t first = k == 0 ? 0 : n - 3;
      idx = {first, first + 1, first + 2};
      at = k - first;
    }
    const Tangent t =
        fit_tangent({q[idx[0]].head<2>(), q[idx[1]].head<2>(), q[idx[2]].head<2>()}, at);
    if (!(t.direction.norm() >= TeachLimits::kMinTangentNorm)) {
      throw InputError(label(points, k) +
                       ": the path turns straight back on itself there, so the side of travel is "
                       "undefined; digitize the turn with more points, or remove " +
                       label(points, k));
    }
    OffsetPoint& o = out.points[k];
    o.taught_mm = q[k];
    o.tangent = t.direction.normalized();
    o.normal = side * Vec2(-o.tangent.y(), o.tangent.x());
    o.tool_mm = q[k];
    o.tool_mm.head<2>() += out.offset_mm * o.normal;
    o.curvature_per_mm = t.curvature_per_mm;
    o.fit = t.fit;
    const double towards_tool = side * t.curvature_per_mm;
    if (towards_tool > 0.0 && 1.0 / towards_tool < out.min_tool_side_radius_mm) {
      out.min_tool_side_radius_mm = 1.0 / towards_tool;
      out.min_tool_side_radius_at = k;
    }
  }
  return out;
}

std::string teach_program(const TeachPath& path, const TeachProgramOptions& o) {
  validate(o);
  if (path.points.empty()) throw InputError("the taught path has no points");
  const auto f = [&o](double v) { return format_fixed(v, o.decimals, o.rounding); };
  const auto xyz = [&f](const Vec3& p) { return "X" + f(p.x()) + "Y" + f(p.y()) + "Z" + f(p.z()); };
  const std::vector<OffsetPoint>& pts = path.points;
  double top_mm = -kInf, length_mm = 0.0;
  std::size_t paper = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    top_mm = std::max(top_mm, pts[i].tool_mm.z());
    if (i + 1 < pts.size() || path.spec.closed) {
      length_mm += (pts[(i + 1) % pts.size()].tool_mm - pts[i].tool_mm).norm();
    }
    if (pts[i].fit == TangentFit::PaperParabola) ++paper;
  }
  const double clear_z_mm = top_mm + o.clearance_mm;
  const TeachSpec& s = path.spec;
  const auto& fp = path.frame.points_mm;
  // One fact per comment line, each short enough for an 80-character controller line buffer.
  std::ostringstream g;
  g << "(ncd teach: deburring path taught off line, paper 003)\n";
  g << "(frame, mm: P1 = " << triple(fp[0]) << " is the origin)\n";
  g << "(P2 = " << triple(fp[1]) << " lies on +X)\n";
  g << "(P3 = " << triple(fp[2]) << " lies in the XY plane)\n";
  g << "(+Z along P1P2 x P1P3: the tool approaches from +Z)\n";
  g << "(tool diameter D = " << given(s.tool_diameter_mm) << ", depth l = " << given(s.depth_mm)
    << ")\n";
  g << "(tool centre D/2 - l = " << given(path.offset_mm) << " " << to_string(s.side)
    << " of the direction of travel, Z as taught)\n";
  g << "(" << pts.size() << " taught points, " << (s.closed ? "closed loop" : "open path") << ")\n";
  g << "(tangent: paper's parabola y = ax^2 + bx + c at " << paper << ", chord quadratic at "
    << pts.size() - paper << ")\n";
  if (std::isinf(path.min_tool_side_radius_mm)) {
    g << "(the path never bends towards the tool: no overcut)\n";
  } else {
    g << "(tightest bend towards the tool: radius " << num(path.min_tool_side_radius_mm)
      << " at point " << path.min_tool_side_radius_at + 1 << ")\n";
    g << (path.min_tool_side_radius_mm < path.offset_mm
              ? "(BELOW D/2 - l: the tool cuts deeper than l there)\n"
              : "(not below D/2 - l: no overcut)\n");
  }
  g << "(coordinates " << (o.rounding == Rounding::Truncate ? "truncated toward zero" : "rounded")
    << " to " << o.decimals << " decimals, mm)\n";
  g << "(F" << shortest(o.feed_mm_per_min) << " mm/min, S" << shortest(o.spindle_rpm)
    << " rpm, cutting length " << num(length_mm) << ", "
    << format_fixed(60.0 * length_mm / o.feed_mm_per_min, 1, Rounding::Nearest) << " s)\n";
  g << "(clearance plane Z" << f(clear_z_mm) << ", " << given(o.clearance_mm)
    << " above the highest point)\n";
  g << "(no tool change: tool " << o.tool << " must be in the spindle)\n";
  if (o.length_offset) {
    g << "(tool length: G43 H" << o.tool << ", the controller's table holds it)\n";
  } else {
    g << "(tool length: no G43 H; set the work offset Z for tool " << o.tool << ")\n";
  }
  g << "G21\n";
  g << "G90F" << shortest(o.feed_mm_per_min) << "S" << shortest(o.spindle_rpm) << "\n";
  if (o.length_offset) g << "G43H" << o.tool << "\n";
  g << "M03\n";
  const Vec3& first = pts.front().tool_mm;
  g << "G00X" << f(first.x()) << "Y" << f(first.y()) << "Z" << f(clear_z_mm) << "\n";
  for (const OffsetPoint& p : pts) g << "G01" << xyz(p.tool_mm) << "\n";
  if (s.closed) g << "G01" << xyz(first) << "\n";
  g << "G00Z" << f(clear_z_mm) << "\n";
  g << "M05\nM30\n";
  return g.str();
}

std::vector<TaughtPoint> parse_points(const std::string& text, const std::string& name) {
  std::vector<TaughtPoint> points;
  std::string_view rest(text);
  if (rest.substr(0, 3) == "\xEF\xBB\xBF") rest.remove_prefix(3);  // a UTF-8 byte-order mark
  bool csv = false, first = true;
  std::array<std::size_t, 3> col{0, 1, 2};  // CSV columns of x, y, z
  std::size_t fields = 3, name_col = std::string::npos;
  for (int line_no = 1; !rest.empty(); ++line_no) {
    const std::size_t eol = rest.find('\n');
    const std::string_view line = trim(rest.substr(0, eol));
    rest.remove_prefix(eol == std::string_view::npos ? rest.size() : eol + 1);
    if (line.empty() || line.front() == '#') continue;
    const std::string where = name + ":" + std::to_string(line_no);
    if (first) {
      first = false;
      csv = line.find(',') != std::string_view::npos;
      if (csv) {
        const std::vector<std::string_view> head = split(line, ',');
        double unused = 0.0;
        if (!std::all_of(head.begin(), head.end(),
                         [&](std::string_view h) { return parse_number(h, unused); })) {
          fields = head.size();
          for (std::size_t a = 0; a < 3; ++a) {
            const std::string axis(1, "xyz"[a]);
            const auto it = std::find_if(head.begin(), head.end(), [&](std::string_view h) {
              return lower(h) == axis || lower(h) == axis + "_mm";
            });
            if (it == head.end()) {
              throw InputError(where + ": the CSV header has no '" + axis +
                               "' column; name the coordinate columns x,y,z (mm)");
            }
            col[a] = static_cast<std::size_t>(it - head.begin());
          }
          const auto it = std::find_if(head.begin(), head.end(),
                                       [](std::string_view h) { return lower(h) == "name"; });
          if (it != head.end()) name_col = static_cast<std::size_t>(it - head.begin());
          continue;
        }
      }
    }
    TaughtPoint p;
    p.line = line_no;
    if (csv) {
      const std::vector<std::string_view> cells = split(line, ',');
      if (cells.size() != fields) {
        throw InputError(where + ": " + std::to_string(cells.size()) + " fields where " +
                         std::to_string(fields) +
                         " are expected; give x,y,z on every line (a header may name more "
                         "columns)");
      }
      for (int a = 0; a < 3; ++a) {
        p.p_mm[a] = coordinate(cells[col[static_cast<std::size_t>(a)]], "xyz"[a], where);
      }
      if (name_col != std::string::npos) p.name = std::string(cells[name_col]);
    } else {
      const std::vector<std::string_view> tokens = split_blank(line);
      if (tokens.size() != 3 && tokens.size() != 4) {
        throw InputError(where + ": " + std::to_string(tokens.size()) +
                         " fields; write one point per line as 'name x y z' or 'x y z' (mm)");
      }
      const std::size_t skip = tokens.size() - 3;
      if (skip) p.name = std::string(tokens[0]);
      for (int a = 0; a < 3; ++a) {
        p.p_mm[a] = coordinate(tokens[skip + static_cast<std::size_t>(a)], "xyz"[a], where);
      }
    }
    points.push_back(std::move(p));
    if (points.size() > TeachLimits::kMaxPoints) {
      throw InputError(name + ": more than " + std::to_string(TeachLimits::kMaxPoints) +
                       " points; split the path into several programs");
    }
  }
  return points;
}

std::array<Vec3, 3> parse_frame_points(const std::string& text, const std::string& what) {
  const std::vector<std::string_view> parts = split(text, ';');
  if (parts.size() != 3) {
    throw InputError(what + " '" + text + "' has " + std::to_string(parts.size()) +
                     " point(s); give three as x,y,z;x,y,z;x,y,z (mm), or a file");
  }
  std::array<Vec3, 3> p;
  for (std::size_t i = 0; i < 3; ++i) {
    const std::vector<std::string_view> c = split(parts[i], ',');
    const std::string where = what + " P" + std::to_string(i + 1);
    if (c.size() != 3) {
      throw InputError(where + " '" + std::string(parts[i]) + "' has " + std::to_string(c.size()) +
                       " coordinate(s); write it as x,y,z (mm)");
    }
    for (int a = 0; a < 3; ++a)
      p[i][a] = coordinate(c[static_cast<std::size_t>(a)], "xyz"[a], where);
  }
  return p;
}

}  // namespace ncd::toolpath
