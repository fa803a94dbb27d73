// Walks a ParametricCurve one interpolation period at a time: given the arc length Δs to
// travel in this period, finds the next parameter u so that the true arc length from the
// current u is Δs. Taylor predictor (paper 004, eq. 7) plus a Newton correction on the true
// arc length; explained in curve_walker.cpp. Real-time safe: step() does not allocate, lock or
// throw; it returns a status.
#pragma once

#include <vector>

#include "geometry/curve.hpp"

namespace ncd::feed {

enum class StepMode {
  Corrected,   // Taylor predictor, then Newton on the true arc length to tolerance_rel
  TaylorOnly,  // eq. (7) alone: the paper's interpolator, the baseline
};

struct WalkerConfig {
  StepMode mode = StepMode::Corrected;
  double tolerance_rel = 1e-10;    // |arc travelled − Δs| ≤ tolerance_rel · Δs (Corrected)
  int max_iterations = 30;         // Newton/bisection updates per step before NotConverged
  bool measure_arc_length = true;  // TaylorOnly: also integrate the true arc length travelled
};

// Ranges that make a WalkerConfig valid.
struct WalkerLimits {
  static constexpr double kMinToleranceRel = 1e-14;
  static constexpr double kMaxToleranceRel = 1e-2;
  static constexpr int kMaxIterations = 1000;
};

// Throws InputError naming the value, the limit and a way out.
void validate(const WalkerConfig& config);

enum class StepStatus {
  Ok,            // moved by Δs (to the tolerance in Corrected mode)
  ReachedEnd,    // u = u_end exactly; the arc travelled is the rest of the curve (≤ Δs)
  NotConverged,  // max_iterations reached; u is the last iterate, the arc is measured there
  Stalled,       // P'(u) = 0 and no correction: TaylorOnly cannot step; u is unchanged
  InvalidStep,   // Δs negative or not finite; u is unchanged
};

struct StepResult {
  double u = 0.0;              // the new parameter
  double arc_length_mm = 0.0;  // true arc length from the previous u (Gauss–Legendre), or NaN
                               // in TaylorOnly mode without measure_arc_length
  int iterations = 0;          // correction iterations after the predictor
  StepStatus status = StepStatus::Ok;
};

class CurveWalker {
 public:
  // Keeps a reference to curve (it must outlive the walker) and copies its breakpoints: the
  // only allocation. Throws InputError on an invalid config, an empty or reversed parameter
  // range, or breakpoints that are unsorted or outside it.
  explicit CurveWalker(const toolpath::ParametricCurve& curve, const WalkerConfig& config = {});

  // Advances by the planned arc length Δs = s(t+T) − s(t) of this period, mm.
  StepResult step(double delta_s_mm);

  double u() const { return u_; }
  bool at_end() const { return u_ >= u_end_; }
  // Restarts at u (clamped to the curve's range).
  void reset(double u);
  // True arc length over [u0, u1] within one span piece per breakpoint (one 5-point
  // Gauss–Legendre panel each), mm; meant for the short interval of one step.
  double arc_length_mm(double u0, double u1) const;

 private:
  StepResult taylor_only(double u_predicted);
  StepResult correct(double delta_s_mm, double u_predicted, double speed_i);
  // ∫ |P'| over [u0, u1] with `rule` applied on each piece between breakpoints (signed).
  template <class Rule>
  double integrate_speed(double u0, double u1, Rule&& rule) const;
  // Arc length of a short Newton update, 3-point Gauss–Legendre per piece.
  double arc_increment_mm(double u0, double u1) const;

  const toolpath::ParametricCurve& curve_;
  WalkerConfig config_;
  std::vector<double> breakpoints_;
  double u_begin_;
  double u_end_;
  double u_;
};

}  // namespace ncd::feed
