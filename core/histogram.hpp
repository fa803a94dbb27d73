// A histogram on logarithmic buckets with fixed memory: percentiles of durations over runs of
// any length (step times, wake-up lateness). 64 buckets per decade from 1 to 1e12 units: a
// percentile is known to within 3.7 %, the maximum exactly.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace ncd {

class LogHistogram {
 public:
  static constexpr int kPerDecade = 64;
  static constexpr int kDecades = 12;
  static constexpr int kBuckets = kPerDecade * kDecades + 1;  // the first holds values < 1

  void add(double value) {
    ++count_;
    if (value > max_) max_ = value;
    const int i = value < 1.0
                      ? 0
                      : 1 + std::min(kBuckets - 2,
                                     static_cast<int>(std::floor(std::log10(value) * kPerDecade)));
    ++buckets_[static_cast<std::size_t>(i)];
  }
  std::int64_t count() const { return count_; }
  double max() const { return max_; }
  // The value below which a fraction q of the samples lie (geometric centre of its bucket;
  // never above the maximum). 0 when empty.
  double quantile(double q) const {
    if (count_ == 0) return 0.0;
    const auto rank = static_cast<std::int64_t>(std::ceil(q * static_cast<double>(count_)));
    std::int64_t seen = 0;
    for (int i = 0; i < kBuckets; ++i) {
      seen += buckets_[static_cast<std::size_t>(i)];
      if (seen >= std::max<std::int64_t>(rank, 1)) {
        if (i == 0) return std::min(0.5, max_);
        return std::min(max_, std::pow(10.0, (i - 0.5) / kPerDecade));
      }
    }
    return max_;
  }
  const std::array<std::int64_t, kBuckets>& buckets() const { return buckets_; }

 private:
  std::array<std::int64_t, kBuckets> buckets_{};
  std::int64_t count_ = 0;
  double max_ = 0.0;
};

}  // namespace ncd
