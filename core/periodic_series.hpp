// The trigonometric interpolant of a smooth 2π-periodic function, and its antiderivative: the
// arc length of a closed curve (paper 000 eq. 28) and its inversion for equal arcs (eqs. 29–33).
//
// Method. Sample f at M = 2^m equispaced angles θ_j = 2π j / M. The discrete Fourier transform
// (radix-2 FFT) gives the coefficients of
//
//     f(θ) ≈ a₀ + Σ_{k=1}^{K} (a_k cos kθ + b_k sin kθ),
//     F(θ) = ∫₀^θ f = a₀ θ + Σ_{k=1}^{K} (a_k sin kθ + b_k (1 − cos kθ)) / k,
//
// and a₀ · 2π is the trapezoidal rule, which for a periodic analytic integrand converges
// geometrically: its error is of the size of the coefficient of order M (the aliased one). If f
// is analytic in a strip |Im θ| < σ, |a_k| and |b_k| fall like e^{−σk}, and the interpolant's
// error is of the size of the coefficients it leaves out.
//
// Acceptance: every coefficient in the top eighth of the band, 3M/8 ≤ k ≤ M/2, is below
// `tolerance` · |a₀|. The band holds at least 8 harmonics, so a symmetry that zeroes every
// second or fourth one cannot fake convergence, and the geometric decay makes everything beyond
// it smaller still. Otherwise M is doubled (the old samples are the even ones of the new grid).
// Where M would exceed the caller's limit (f nearly singular near the real axis) no series is
// returned, and the caller must use a method that is local in θ (composite Gauss–Legendre in
// cam/chamfer.cpp). The FFT's rounding leaves every coefficient with a noise of about
// 10⁻¹⁶ |a₀|, so a tolerance much below 10⁻¹⁴ would only measure that noise; harmonics past the
// last one above 10⁻² · tolerance · |a₀| are left out of the evaluation.
//
// Evaluation rotates (cos kθ, sin kθ) by 2θ along two independent chains, odd and even k (the
// two halve the latency of one chain): rounding grows like k·ε, which for the K < 2048 harmonics
// allowed here stays below 1e-12 relative and in practice near 1e-15.
#pragma once

#include <functional>
#include <optional>
#include <vector>

namespace ncd {

class PeriodicSeries {
 public:
  // The series of f from at least max(64, min_samples) and at most `max_samples` samples (powers
  // of two); nullopt when the coefficients do not fall below tolerance · |a₀| within max_samples.
  static std::optional<PeriodicSeries> fit(const std::function<double(double)>& f, double tolerance,
                                           int min_samples, int max_samples);

  struct Sample {
    double value = 0.0;     // f(θ)
    double integral = 0.0;  // F(θ) = ∫₀^θ f
    double slope = 0.0;     // f'(θ)
  };

  double mean() const { return a0_; }                            // a₀, the average of f
  double period_integral() const;                                // ∫₀^{2π} f = 2π a₀
  double value(double theta) const;                              // f(θ)
  double integral(double theta) const;                           // F(θ) = ∫₀^θ f
  Sample at(double theta) const;                                 // all three at once
  int samples() const { return samples_; }                       // M
  int harmonics() const { return static_cast<int>(a_.size()); }  // K, after trimming

 private:
  double a0_ = 0.0;
  std::vector<double> a_, b_;                  // a_k, b_k for k = 1..K
  std::vector<double> a_over_k_, b_over_k_;    // a_k / k, b_k / k
  std::vector<double> a_times_k_, b_times_k_;  // k a_k, k b_k
  double b_over_k_sum_ = 0.0;                  // Σ b_k / k = F's constant
  int samples_ = 0;
};

}  // namespace ncd
