// Off-line teaching of a deburring path (paper 003, Kim, Park, Lee, with the conventions of
// docs/teach.md): digitized points → three-point frame → tool-radius offset → NC program. The
// algorithm is explained once, in teach.cpp.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "core/geometry.hpp"

namespace ncd::toolpath {

// Side of the direction of travel the tool centre lies on (the side away from the material).
enum class TravelSide { Left, Right };
std::string to_string(TravelSide side);

// How a number is cut to the program's precision.
enum class Rounding { Nearest, Truncate };

// Which fit gave the tangent at a point (see teach.cpp).
enum class TangentFit { PaperParabola, ChordQuadratic };

// Limits that make a teaching job valid, shared by validation and its error messages.
struct TeachLimits {
  static constexpr std::size_t kMinPoints = 3;  // the parabola of §3.3 needs three
  static constexpr std::size_t kMaxPoints = 1000000;
  static constexpr double kMaxCoordinateMm = 1e6;  // a kilometre: anything larger is a unit slip
  static constexpr double kMinSpacingMm = 1e-3;    // neighbours closer than this in the frame's XY
  static constexpr double kMinFrameSpacingMm = 1.0;  // between any two frame points
  static constexpr double kMinFrameAngleDeg = 1.0;   // ∠P2 P1 P3 kept away from 0° and 180°
  // The paper's y(x) parabola is used only where both chords are within this angle of X.
  static constexpr double kPaperFitMaxChordAngleDeg = 60.0;
  // |dp/dt| of the chord-length fit below this: the path turns straight back on itself.
  static constexpr double kMinTangentNorm = 1e-9;
  static constexpr int kMinDecimals = 1;
  static constexpr int kMaxDecimals = 6;
};

// One digitized point as read, with where it came from for messages.
struct TaughtPoint {
  Vec3 p_mm;
  std::string name;  // label from the file ("dp1"), or empty
  int line = 0;      // 1-based line of the source, 0 when not from a file
};

// The input frame of §3.2: P1 the origin, P2 on +X, P3 in the XY plane (eqs. 1–18).
struct TeachFrame {
  std::array<Vec3, 3> points_mm;  // P1, P2, P3 as given
  Eigen::Matrix3d r;              // R = [e_x e_y e_z], columns are unit vectors
  Vec3 to_frame(const Vec3& p_mm) const { return r.transpose() * (p_mm - points_mm[0]); }
};

// Throws InputError when two frame points are closer than kMinFrameSpacingMm or the three are
// (nearly) collinear; `what` names them in the message (a flag, a file).
TeachFrame make_frame(const std::array<Vec3, 3>& points_mm, const std::string& what);

// Everything that defines one teaching job. Lengths in mm.
struct TeachSpec {
  double tool_diameter_mm = 10.0;  // D
  double depth_mm = 0.2;           // deburring depth l
  TravelSide side = TravelSide::Left;
  bool closed = false;  // the last point joins the first; neighbours wrap around
};

// Throws InputError naming the value, the limit and a way out (D, l, D/2 − l > 0).
void validate(const TeachSpec& spec);

// One taught point and the tool centre offset from it, in the frame.
struct OffsetPoint {
  Vec3 taught_mm;                 // p' = Rᵀ (p − P1)
  Vec3 tool_mm;                   // p' + (D/2 − l) n, Z kept
  Eigen::Vector2d tangent;        // unit, in the frame's XY, along the direction of travel
  Eigen::Vector2d normal;         // unit, in the frame's XY, towards the tool
  double curvature_per_mm = 0.0;  // of the chord-length quadratic in XY, > 0 turning left
  TangentFit fit = TangentFit::PaperParabola;
};

struct TeachPath {
  TeachSpec spec;
  TeachFrame frame;
  std::vector<OffsetPoint> points;  // one per taught point
  double offset_mm = 0.0;           // D/2 − l
  // Smallest radius of curvature where the path bends towards the tool (+inf if nowhere) and
  // the point it is at; an offset above it cuts deeper than l there.
  double min_tool_side_radius_mm = 0.0;
  std::size_t min_tool_side_radius_at = 0;
};

// The whole offset of §3.3 (eqs. 19–20 and the fallback of teach.cpp). Throws InputError for
// fewer than three points, non-finite coordinates, neighbours closer than kMinSpacingMm in the
// frame's XY plane, a path that turns straight back on itself, or an invalid spec.
TeachPath teach(const std::vector<TaughtPoint>& points, const TeachFrame& frame,
                const TeachSpec& spec);

struct TeachProgramOptions {
  double feed_mm_per_min = 300.0;  // the paper's program
  double spindle_rpm = 2000.0;
  int decimals = 3;  // digits after the point in coordinates (the paper's)
  Rounding rounding = Rounding::Nearest;
  double clearance_mm = 10.0;  // approach and retract plane above the highest tool point (+Z)
  // The tool in the spindle (the program changes none): "G43 H tool" before the first move, so
  // that a controller with a tool table (LinuxCNC, Fanuc) drives the tool's point, not the
  // spindle's gauge line. length_offset false (a controller without a table, grbl): no G43 H;
  // the header says to set the length in the work offset.
  int tool = 1;
  bool length_offset = true;
};

// Throws InputError when an option is out of range.
void validate(const TeachProgramOptions& options);

// The NC program: a header comment stating the frame, D, l, side, precision and the checks,
// then G21, G90 F S, G43 H (options.length_offset), M03, a rapid above the first point, one G01 X Y
// Z per point (the first again at the end of a closed loop), a rapid retract, M05, M30. No % lines.
std::string teach_program(const TeachPath& path, const TeachProgramOptions& options);

// v with exactly `decimals` digits after the point: rounded to nearest (the binary value), or
// truncated toward zero (the shortest decimal that reads back as v). Never "-0.000".
std::string format_fixed(double v, int decimals, Rounding rounding);

// Digitized points from text: CSV with a header naming x, y, z columns (a `name` column is
// kept, others ignored) or headerless x,y,z rows; or whitespace-separated `name x y z` or
// `x y z` lines. Blank lines and lines starting with '#' are skipped. `name` (a file name)
// prefixes every error, with the line. Throws InputError.
std::vector<TaughtPoint> parse_points(const std::string& text, const std::string& name);

// Three frame points written inline as "x,y,z;x,y,z;x,y,z"; `what` (a flag) prefixes every
// error. Throws InputError.
std::array<Vec3, 3> parse_frame_points(const std::string& text, const std::string& what);

}  // namespace ncd::toolpath
