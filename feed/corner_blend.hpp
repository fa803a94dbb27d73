// Corner blending under G64 P (path tolerance): the corners of straight moves are replaced by
// circular arcs that stay within P of the programmed corner. The algorithm and its decisions
// are explained in corner_blend.cpp and docs/planner.md §3a.
#pragma once

#include <cstddef>
#include <vector>

#include "feed/feed_limits.hpp"
#include "geometry/path.hpp"

namespace ncd::feed {

// A corner that could have been rounded but was kept sharp because the arc is slower than
// passing it sharp or stopping there (motion/corner_overlap.hpp may pass it without its stop).
struct SharpCorner {
  Vec3 vertex_mm = Vec3::Zero();
  Vec3 d_in = Vec3::Zero(), d_out = Vec3::Zero();  // unit directions of the pieces
  double tolerance_mm = 0.0;                       // the move's G64 P
  double in_mm = 0.0, out_mm = 0.0;                // straight length on each side of the vertex
  std::size_t segment = 0;                         // the move that ends at the vertex or holds it
};

struct BlendReport {
  std::size_t corners = 0;         // corners replaced by an arc
  double max_deviation_mm = 0.0;   // largest distance of an arc from its programmed corner
  std::vector<SharpCorner> sharp;  // blendable corners kept sharp, in path order
};

// The path with its blendable corners rounded (see corner_blend.cpp). The segment count and
// order are kept (an arc belongs to the move that ends at its corner, which then becomes a
// rational quadratic NURBS; the next move starts where the arc ends), so that a segment index
// still names the programmed move. Corners that are not blended are left exactly as given.
toolpath::Path blend_corners(const toolpath::Path& path, const MachineLimits& limits,
                             BlendReport* report = nullptr);

// The speed of the chord and junction rules at a corner turning by phi between two straight
// pieces (docs/planner.md §2): what the limit sampler allows there without blending, mm/s.
// Under JerkBound::vector also the direction change's law, jump_feed_mm_per_s (§3c).
double polyline_corner_speed_mm_per_s(const MachineLimits& limits, double phi_rad,
                                      double curvature_per_mm = 0.0);

}  // namespace ncd::feed
