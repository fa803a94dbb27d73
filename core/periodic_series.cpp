// The trigonometric interpolant and its antiderivative; the method is at the top of the header.
#include "core/periodic_series.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>
#include <numbers>

namespace ncd {

namespace {

using Complex = std::complex<double>;

// In-place radix-2 FFT, x_k ← Σ_j x_j e^{−2πi jk/n}, n a power of two. The twiddles are exact
// cosines and sines of the first eighth of the circle, the rest by the circle's symmetries
// (cos(π/2 − x) = sin x, cos(π − x) = −cos x); not from a recurrence. The butterflies are
// written out in real arithmetic (std::complex's product checks for NaN and goes through
// memory).
void fft(std::vector<Complex>& x) {
  const std::size_t n = x.size();
  for (std::size_t i = 1, j = 0; i < n; ++i) {  // bit-reversal permutation
    std::size_t bit = n >> 1;
    for (; j & bit; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(x[i], x[j]);
  }
  // cos and −sin of 2π k / n for k < n/2.
  std::vector<double> tw_re(n / 2), tw_im(n / 2);
  const std::size_t eighth = n / 8, quarter = n / 4;
  for (std::size_t k = 0; k <= eighth && k < n / 2; ++k) {
    const double angle = 2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(n);
    tw_re[k] = std::cos(angle);
    tw_im[k] = -std::sin(angle);
  }
  for (std::size_t k = eighth + 1; k <= quarter && k < n / 2; ++k) {
    tw_re[k] = -tw_im[quarter - k];
    tw_im[k] = -tw_re[quarter - k];
  }
  for (std::size_t k = quarter + 1; k < n / 2; ++k) {
    tw_re[k] = -tw_re[n / 2 - k];
    tw_im[k] = tw_im[n / 2 - k];
  }
  for (std::size_t len = 2; len <= n; len <<= 1) {
    const std::size_t stride = n / len;
    for (std::size_t start = 0; start < n; start += len) {
      for (std::size_t k = 0; k < len / 2; ++k) {
        const std::size_t i = start + k, j = i + len / 2;
        const double wr = tw_re[k * stride], wi = tw_im[k * stride];
        const double ur = x[i].real(), ui = x[i].imag();
        const double vr = x[j].real() * wr - x[j].imag() * wi;
        const double vi = x[j].real() * wi + x[j].imag() * wr;
        x[i] = {ur + vr, ui + vi};
        x[j] = {ur - vr, ui - vi};
      }
    }
  }
}

// Samples f(2π j / n) for j = 0..n−1, reusing the n/2 samples of the coarser grid.
std::vector<double> refine(const std::function<double(double)>& f, const std::vector<double>& old,
                           std::size_t n) {
  std::vector<double> out(n);
  const double step = 2.0 * std::numbers::pi / static_cast<double>(n);
  for (std::size_t j = 0; j < n; ++j) {
    out[j] = (j % 2 == 0 && old.size() * 2 == n) ? old[j / 2] : f(step * static_cast<double>(j));
  }
  return out;
}

}  // namespace

std::optional<PeriodicSeries> PeriodicSeries::fit(const std::function<double(double)>& f,
                                                  double tolerance, int min_samples,
                                                  int max_samples) {
  std::vector<double> samples;
  std::size_t n = 64;  // at least 8 harmonics in the band checked
  while (n < static_cast<std::size_t>(min_samples)) n *= 2;
  for (; n <= static_cast<std::size_t>(max_samples); n *= 2) {
    samples = refine(f, samples, n);
    std::vector<Complex> c(samples.begin(), samples.end());
    fft(c);
    const double scale = 1.0 / static_cast<double>(n);
    const double a0 = c[0].real() * scale;
    // a_k = 2 Re c_k / n, b_k = −2 Im c_k / n for 0 < k < n/2 (the Nyquist term is left out: it
    // is below the tolerance whenever the series is accepted).
    double band = 0.0;  // the top eighth of the band, 3n/8 ≤ k ≤ n/2
    for (std::size_t k = 3 * n / 8; k <= n / 2; ++k) {
      band = std::max(band, 2.0 * std::abs(c[k]) * scale);
    }
    if (!(band <= tolerance * std::abs(a0))) continue;
    PeriodicSeries s;
    s.a0_ = a0;
    s.samples_ = static_cast<int>(n);
    std::size_t last = 0;  // the highest harmonic that can still change a digit
    for (std::size_t k = 1; k < n / 2; ++k) {
      if (2.0 * std::abs(c[k]) * scale > 1e-2 * tolerance * std::abs(a0)) last = k;
    }
    for (std::size_t k = 1; k <= last; ++k) {
      s.a_.push_back(2.0 * c[k].real() * scale);
      s.b_.push_back(-2.0 * c[k].imag() * scale);
      s.a_over_k_.push_back(s.a_.back() / static_cast<double>(k));
      s.b_over_k_.push_back(s.b_.back() / static_cast<double>(k));
      s.a_times_k_.push_back(s.a_.back() * static_cast<double>(k));
      s.b_times_k_.push_back(s.b_.back() * static_cast<double>(k));
      s.b_over_k_sum_ += s.b_over_k_.back();
    }
    return s;
  }
  return std::nullopt;
}

double PeriodicSeries::period_integral() const {
  return 2.0 * std::numbers::pi * a0_;
}

PeriodicSeries::Sample PeriodicSeries::at(double theta) const {
  const double c1 = std::cos(theta), s1 = std::sin(theta);
  const double c2 = c1 * c1 - s1 * s1, s2 = 2.0 * s1 * c1;  // the step of both chains, 2θ
  double c_odd = c1, s_odd = s1, c_even = c2, s_even = s2;  // cos kθ, sin kθ, k odd and even
  double value[2] = {a0_, 0.0}, integral[2] = {a0_ * theta + b_over_k_sum_, 0.0};
  double slope[2] = {0.0, 0.0};
  const auto add = [&](std::size_t i, int chain, double c, double s) {
    value[chain] += a_[i] * c + b_[i] * s;
    integral[chain] += a_over_k_[i] * s - b_over_k_[i] * c;
    slope[chain] += b_times_k_[i] * c - a_times_k_[i] * s;
  };
  const std::size_t n = a_.size();
  std::size_t i = 0;
  for (; i + 1 < n; i += 2) {  // harmonics i + 1 (odd) and i + 2 (even)
    add(i, 0, c_odd, s_odd);
    add(i + 1, 1, c_even, s_even);
    const double c_odd_next = c_odd * c2 - s_odd * s2;
    s_odd = s_odd * c2 + c_odd * s2;
    c_odd = c_odd_next;
    const double c_even_next = c_even * c2 - s_even * s2;
    s_even = s_even * c2 + c_even * s2;
    c_even = c_even_next;
  }
  if (i < n) add(i, 0, c_odd, s_odd);
  return {value[0] + value[1], integral[0] + integral[1], slope[0] + slope[1]};
}

double PeriodicSeries::value(double theta) const {
  return at(theta).value;
}

double PeriodicSeries::integral(double theta) const {
  return at(theta).integral;
}

}  // namespace ncd
