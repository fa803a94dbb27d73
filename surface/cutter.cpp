// The rotating edges of a ball-end mill over a Z-map (docs/surface-simulation.md §3).
//
// Tool. A ball of radius r, centre C(t) = tip(t) + r·Z, carries z edges on its lower hemisphere.
// Edge k at polar angle φ from the tip (0 ≤ φ ≤ π/2) is the point
//
//     C + r (sin φ cos θ_k, sin φ sin θ_k, −cos φ),  θ_k = θ(t) + 2πk/z − s·λ(φ),
//
// with θ(t) = θ_0 + s·ω (t − t_0) the spindle angle (s = −1 for M3, clockwise seen from the
// spindle), ω = 2πN/60, and λ(φ) = tan(i)(1 − cos φ) the lag of a helical edge of lead angle i
// (λ = 0: straight edges in axial planes, the default). Straight edges of a 2-tooth tool meet at
// the tip, so the tip, where the cutting speed is zero, is on an edge: the paper's dead centre
// (its eq. 3) arises from the kinematics alone, with no rubbing model.
//
// Min-z. Each time step, each edge is sampled at polar angles φ_j = j·Δφ; the sample falls on a
// cell, and the cell's height becomes min(height, C_z − sqrt(r² − ρ_c²)), ρ_c the horizontal
// distance from the axis to the cell's centre: the height of the sphere over that centre, at the
// moment an edge passes over the cell. Heights are therefore exact on the sphere; the only
// approximation is when an edge is deemed to pass a cell, which is off by at most one time step.
//
// Time resolution. Samples are at most sample_fraction·h apart along the edge (Δφ r ≤ s), and
// between steps no sample moves further than s = sample_fraction·h: Δt = s / (ω ρ_hi + v), ρ_hi
// the largest distance from the axis of an edge point that can cut, v the speed of the move.
// With s ≤ h/√2 the samples of consecutive steps leave no cell of the swept band unvisited.
// The step thus resolves the tooth passes whatever the spacing of the setpoints: a move between
// two 4 ms setpoints is split into as many steps as its rotation needs.
//
// Only what can cut is visited. An edge point above the initial surface's bounding plane
// z = z0 + gx x + gy y cannot remove anything; the points below form a spherical cap around the
// direction n = (gx, gy, −1)/L (L = sqrt(1 + gx² + gy²)) of half-angle β, cos β = d/r, d the
// smallest distance from the centre to the plane over the move. On an edge at azimuth θ,
// p(φ)·n = (c sin φ + cos φ)/L with c = gx cos θ + gy sin θ, so the edge's part in the cap is
// |φ − atan c| ≤ acos(L cos β / sqrt(1 + c²)): a closed form per edge and step. The cap's
// horizontal footprint lies within 2 r sin(β/2) of the contact point's projection r (gx, gy)/L.
//
// Tiles. The grid is split into square tiles that the threads take in turn; each tile walks
// only the steps whose footprint meets it (a clip of the move's straight line against the
// tile, grown by the footprint's reach), and of each straight edge only the part over the tile
// (a ray–box clip). Tiles share no cell, so there is no locking, and the result is the same
// for any number of threads. The work is proportional to the swept length times the cap's area
// over s², not to the size of the grid.
#include "surface/cutter.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <thread>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::surface {
namespace {

// One move, precomputed for the tiles.
struct MoveGeom {
  double cx0, cy0, cz0;   // centre at t0
  double dcx, dcy, dcz;   // change of the centre over the move
  double theta0, dtheta;  // spindle angle at t0 and its change over the move
  double cos_beta;        // cap: edge points with p·n ≥ cos β are below the bounding plane
  double phi_lo, phi_hi;  // polar range of the cap over all azimuths
  double reach_mm;        // footprint half-size around the contact point
  double rho_hi_mm;       // largest distance from the axis of an edge point in the cap
  std::int64_t steps;     // samples m = 0..steps
  std::int32_t index;
};

constexpr double kMaxSteps = 1e10;  // hours of computing: a clear limit, not a hang

struct Tile {
  int i0, i1, j0, j1;  // cells [i0, i1) × [j0, j1)
};

// m ∈ [lo, hi] with |a + b m − c| ≤ w, intersected into [lo, hi].
void clip_axis(double a, double b, double c, double w, double& lo, double& hi) {
  if (std::abs(b) < 1e-300) {
    if (std::abs(a - c) > w) hi = lo - 1.0;
    return;
  }
  double m1 = (c - w - a) / b, m2 = (c + w - a) / b;
  if (m1 > m2) std::swap(m1, m2);
  lo = std::max(lo, m1);
  hi = std::min(hi, m2);
}

// ρ ∈ [lo, hi] with p + ρ d inside [b0, b1) on one axis.
void clip_ray(double p, double d, double b0, double b1, double& lo, double& hi) {
  if (std::abs(d) < 1e-15) {
    if (p < b0 || p >= b1) hi = lo - 1.0;
    return;
  }
  double r1 = (b0 - p) / d, r2 = (b1 - p) / d;
  if (r1 > r2) std::swap(r1, r2);
  lo = std::max(lo, r1);
  hi = std::min(hi, r2);
}

class Cutter {
 public:
  Cutter(ZMap& map, const BallEndMill& tool, const std::vector<Move>& moves, double sample_mm)
      : map_(map), r_(tool.radius_mm), r2_(tool.radius_mm * tool.radius_mm) {
    const InitialSurface& s = map.initial();
    gx_ = s.grad_x;
    gy_ = s.grad_y;
    len_ = std::sqrt(1.0 + gx_ * gx_ + gy_ * gy_);
    const double tan_i = std::tan(deg_to_rad(tool.helix_deg));
    helix_ = tool.helix_deg != 0.0;
    dphi_ = sample_mm / (r_ * std::sqrt(1.0 + tan_i * tan_i));
    const auto n_phi = static_cast<std::size_t>(std::floor(0.5 * kPi / dphi_)) + 1;
    rsin_.resize(n_phi);
    rcos_.resize(n_phi);
    lag_.resize(n_phi);
    const double sgn = tool.clockwise ? -1.0 : 1.0;
    for (std::size_t j = 0; j < n_phi; ++j) {
      const double phi = std::min(0.5 * kPi, static_cast<double>(j) * dphi_);
      rsin_[j] = r_ * std::sin(phi);
      rcos_[j] = r_ * std::cos(phi);
      lag_[j] = -sgn * tan_i * (1.0 - std::cos(phi));
    }
    const double omega = 2.0 * kPi * tool.spindle_rpm / 60.0;
    const double slope = std::atan(std::sqrt(gx_ * gx_ + gy_ * gy_));
    for (std::size_t k = 0; k < moves.size(); ++k) {
      const Move& mv = moves[k];
      MoveGeom g{};
      g.index = static_cast<std::int32_t>(k);
      const Vec3 c0 = mv.from_mm + Vec3(0, 0, r_), c1 = mv.to_mm + Vec3(0, 0, r_);
      g.cx0 = c0.x();
      g.cy0 = c0.y();
      g.cz0 = c0.z();
      g.dcx = c1.x() - c0.x();
      g.dcy = c1.y() - c0.y();
      g.dcz = c1.z() - c0.z();
      const double dt = mv.t1_s - mv.t0_s;
      g.theta0 = mv.spindle0_rad;
      g.dtheta = sgn * omega * dt;
      const double d0 = (c0.z() - s.plane_mm(c0.x(), c0.y())) / len_;
      const double d1 = (c1.z() - s.plane_mm(c1.x(), c1.y())) / len_;
      g.cos_beta = std::max(-1.0, std::min(d0, d1) / r_);
      if (g.cos_beta >= 1.0) continue;  // the ball stays above the surface
      const double beta = std::acos(g.cos_beta);
      g.phi_lo = std::max(0.0, slope - beta);
      g.phi_hi = std::min(0.5 * kPi, slope + beta);
      g.reach_mm = 2.0 * r_ * std::sin(0.5 * beta) + map.cell_mm();
      const double rho_hi = r_ * std::sin(g.phi_hi);
      g.rho_hi_mm = rho_hi + map.cell_mm();
      const double v = std::hypot(g.dcx, g.dcy) / std::max(dt, 1e-300);
      const double steps = dt > 0.0 ? std::ceil(dt * (omega * rho_hi + v) / sample_mm) : 0.0;
      if (steps > kMaxSteps) {
        throw InputError("move " + std::to_string(k) + " lasts " + text::sig(dt) + " s and needs " +
                         text::sig(steps) + " time steps at a cell of " + text::sig(map.cell_mm()) +
                         " mm, above " + text::sig(kMaxSteps) +
                         ": simulate a shorter stretch of the run or use a coarser cell");
      }
      g.steps = static_cast<std::int64_t>(steps);
      g.steps = std::max<std::int64_t>(g.steps, dt > 0.0 ? 1 : 0);
      steps_total_ += g.steps + 1;
      geoms_.push_back(g);
    }
    ox_ = r_ * gx_ / len_;
    oy_ = r_ * gy_ / len_;
    teeth_ = tool.teeth;
    inv_h_ = 1.0 / map.cell_mm();
  }

  std::int64_t steps_total() const { return steps_total_; }

  // Cuts every move into one tile; returns the cell updates.
  std::int64_t cut(const Tile& t) {
    const double h = map_.cell_mm();
    const double bx0 = map_.x0_mm() + t.i0 * h, bx1 = map_.x0_mm() + t.i1 * h;
    const double by0 = map_.y0_mm() + t.j0 * h, by1 = map_.y0_mm() + t.j1 * h;
    std::int64_t updates = 0;
    for (const MoveGeom& g : geoms_) {
      double lo = 0.0, hi = static_cast<double>(g.steps);
      const double n = std::max<double>(1.0, static_cast<double>(g.steps));
      clip_axis(g.cx0 + ox_, g.dcx / n, 0.5 * (bx0 + bx1), 0.5 * (bx1 - bx0) + g.reach_mm, lo, hi);
      clip_axis(g.cy0 + oy_, g.dcy / n, 0.5 * (by0 + by1), 0.5 * (by1 - by0) + g.reach_mm, lo, hi);
      if (lo > hi) continue;
      const auto m0 = static_cast<std::int64_t>(std::ceil(lo));
      const auto m1 = static_cast<std::int64_t>(std::floor(hi));
      for (std::int64_t m = m0; m <= m1; ++m) {
        const double u = static_cast<double>(m) / n;
        const double cx = g.cx0 + u * g.dcx, cy = g.cy0 + u * g.dcy, cz = g.cz0 + u * g.dcz;
        const double theta = g.theta0 + u * g.dtheta;
        for (int k = 0; k < teeth_; ++k) {
          const double th = theta + 2.0 * kPi * k / teeth_;
          updates += helix_ ? edge_helix(t, g, cx, cy, cz, th)
                            : edge_straight(t, g, cx, cy, cz, th, bx0, bx1, by0, by1);
        }
      }
    }
    return updates;
  }

 private:
  // Lowers one cell; returns whether the sample fell on the tile.
  bool lower(const Tile& t, double px, double py, double cx, double cy, double cz, double rcos,
             std::int32_t index, int& last_i, int& last_j) {
    const double fi = (px - map_.x0_mm()) * inv_h_, fj = (py - map_.y0_mm()) * inv_h_;
    if (!(fi >= t.i0 && fi < t.i1 && fj >= t.j0 && fj < t.j1)) return false;
    const int i = static_cast<int>(fi), j = static_cast<int>(fj);
    if (i == last_i && j == last_j) return false;
    last_i = i;
    last_j = j;
    const double dx = map_.x_mm(i) - cx, dy = map_.y_mm(j) - cy;
    const double q = r2_ - dx * dx - dy * dy;
    const double z = q > 0.0 ? cz - std::sqrt(q) : cz - rcos;
    double& cell = map_.z_row(j)[i];
    if (z < cell) {
      cell = z;
      map_.cut_row(j)[i] = index;
    }
    return true;
  }

  std::int64_t edge_straight(const Tile& t, const MoveGeom& g, double cx, double cy, double cz,
                             double th, double bx0, double bx1, double by0, double by1) {
    const double ct = std::cos(th), st = std::sin(th);
    // The part of the edge over the tile first (no trigonometry), then the cap.
    double rlo = 0.0, rhi = g.rho_hi_mm;
    clip_ray(cx, ct, bx0, bx1, rlo, rhi);
    clip_ray(cy, st, by0, by1, rlo, rhi);
    if (rlo > rhi) return 0;
    const double c = gx_ * ct + gy_ * st;
    const double q = len_ * g.cos_beta / std::sqrt(1.0 + c * c);
    if (q > 1.0) return 0;
    const double delta = q <= -1.0 ? kPi : std::acos(q);
    const double phi0 = std::atan(c);
    const double phi_lo = std::max(0.0, phi0 - delta), phi_hi = std::min(0.5 * kPi, phi0 + delta);
    if (phi_lo > phi_hi) return 0;
    const double plo = std::asin(std::min(1.0, std::max(0.0, rlo) / r_));
    const double phi_hi_tile = std::asin(std::min(1.0, rhi / r_));
    const auto last = static_cast<std::int64_t>(rsin_.size()) - 1;
    const std::int64_t j0 =
        std::max<std::int64_t>(static_cast<std::int64_t>(std::ceil(phi_lo / dphi_ - 1e-9)),
                               static_cast<std::int64_t>(std::floor(plo / dphi_)));
    const std::int64_t j1 =
        std::min<std::int64_t>({static_cast<std::int64_t>(std::floor(phi_hi / dphi_ + 1e-9)),
                                static_cast<std::int64_t>(std::ceil(phi_hi_tile / dphi_)), last});
    std::int64_t n = 0;
    int li = -1, lj = -1;
    for (std::int64_t j = j0; j <= j1; ++j) {
      const auto ju = static_cast<std::size_t>(j);
      n += lower(t, cx + rsin_[ju] * ct, cy + rsin_[ju] * st, cx, cy, cz, rcos_[ju], g.index, li,
                 lj);
    }
    return n;
  }

  std::int64_t edge_helix(const Tile& t, const MoveGeom& g, double cx, double cy, double cz,
                          double th) {
    const auto last = static_cast<std::int64_t>(rsin_.size()) - 1;
    const auto j0 = static_cast<std::int64_t>(std::floor(g.phi_lo / dphi_));
    const auto j1 = std::min(last, static_cast<std::int64_t>(std::ceil(g.phi_hi / dphi_)));
    std::int64_t n = 0;
    int li = -1, lj = -1;
    for (std::int64_t j = j0; j <= j1; ++j) {
      const auto ju = static_cast<std::size_t>(j);
      const double a = th + lag_[ju];
      n += lower(t, cx + rsin_[ju] * std::cos(a), cy + rsin_[ju] * std::sin(a), cx, cy, cz,
                 rcos_[ju], g.index, li, lj);
    }
    return n;
  }

  ZMap& map_;
  double r_, r2_;
  double gx_ = 0.0, gy_ = 0.0, len_ = 1.0, ox_ = 0.0, oy_ = 0.0;
  bool helix_ = false;
  int teeth_ = 1;
  double dphi_ = 0.0, inv_h_ = 1.0;
  std::vector<double> rsin_, rcos_, lag_;
  std::vector<MoveGeom> geoms_;
  std::int64_t steps_total_ = 0;
};

}  // namespace

void validate(const BallEndMill& tool) {
  require_positive("ball_radius_mm", tool.radius_mm);
  require_positive("spindle_rpm", tool.spindle_rpm);
  if (tool.teeth < 1 || tool.teeth > 64) {
    throw InputError("teeth = " + std::to_string(tool.teeth) +
                     " is outside [1, 64]: give the number of cutting edges of the ball");
  }
  if (!std::isfinite(tool.helix_deg) || tool.helix_deg < 0.0 || tool.helix_deg >= 60.0) {
    throw InputError("helix_deg = " + text::sig(tool.helix_deg) +
                     " is outside [0, 60): give the lead angle of the edges, 0 for straight edges");
  }
}

SimStats simulate(ZMap& map, const BallEndMill& tool, const std::vector<Move>& moves,
                  const SimOptions& options) {
  validate(tool);
  if (!(options.sample_fraction > 0.0 && options.sample_fraction <= 1.0)) {
    throw InputError("sample_fraction = " + text::sig(options.sample_fraction) +
                     " is outside (0, 1]: samples must be at most one cell apart");
  }
  if (options.tile_cells < 8) {
    throw InputError("tile_cells = " + std::to_string(options.tile_cells) + " is below 8");
  }
  if (moves.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw InputError("there are " + std::to_string(moves.size()) +
                     " moves, above 2^31 - 1: simulate a shorter stretch of the run");
  }
  for (std::size_t k = 0; k < moves.size(); ++k) {
    const Move& m = moves[k];
    if (!m.from_mm.allFinite() || !m.to_mm.allFinite() || !std::isfinite(m.t0_s) ||
        !std::isfinite(m.t1_s) || !std::isfinite(m.spindle0_rad)) {
      throw InputError("move " + std::to_string(k) + " has a coordinate, time or angle that is " +
                       "not finite: check the setpoints");
    }
    if (m.t1_s < m.t0_s) {
      throw InputError("move " + std::to_string(k) + " ends at t = " + text::sig(m.t1_s) +
                       " s before it starts at t = " + text::sig(m.t0_s) +
                       " s: setpoints must be in time order");
    }
  }
  const auto start = std::chrono::steady_clock::now();
  Cutter cutter(map, tool, moves, options.sample_fraction * map.cell_mm());
  std::vector<Tile> tiles;
  const int ts = options.tile_cells;
  for (int j = 0; j < map.ny(); j += ts) {
    for (int i = 0; i < map.nx(); i += ts) {
      tiles.push_back({i, std::min(i + ts, map.nx()), j, std::min(j + ts, map.ny())});
    }
  }
  int threads =
      options.threads > 0 ? options.threads : static_cast<int>(std::thread::hardware_concurrency());
  threads = std::max(1, std::min(threads, static_cast<int>(tiles.size())));
  std::atomic<std::size_t> next{0};
  std::atomic<std::int64_t> updates{0};
  auto worker = [&] {
    std::int64_t mine = 0;
    for (std::size_t k = next++; k < tiles.size(); k = next++) mine += cutter.cut(tiles[k]);
    updates += mine;
  };
  {
    std::vector<std::jthread> pool;
    for (int k = 1; k < threads; ++k) pool.emplace_back(worker);
    worker();
  }
  SimStats st;
  st.cell_updates = updates.load();
  st.time_steps = cutter.steps_total();
  st.threads = threads;
  st.tiles = static_cast<int>(tiles.size());
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return st;
}

}  // namespace ncd::surface
