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

  // The coarse view (a status page's histogram): kCoarsePerDecade buckets per decade, each the
  // sum of kPerDecade / kCoarsePerDecade buckets, so that a coarse count kept on its own (by
  // coarse_of(bucket_of(value))) equals the sum of the fine ones exactly. Coarse bucket 0 holds
  // the values < 1; bucket g >= 1 holds [coarse_from(g), coarse_from(g + 1)).
  static constexpr int kCoarsePerDecade = 8;
  static constexpr int kCoarseBuckets = 1 + kDecades * kCoarsePerDecade;

  // The bucket of a value: 0 below 1, else 1 + floor(64 log10(value)) (the last one above 1e12).
  static int bucket_of(double value) {
    return value < 1.0 ? 0
                       : 1 + std::min(kBuckets - 2,
                                      static_cast<int>(std::floor(std::log10(value) * kPerDecade)));
  }
  static int coarse_of(int bucket) {
    return bucket == 0 ? 0 : 1 + (bucket - 1) / (kPerDecade / kCoarsePerDecade);
  }
  static double coarse_from(int coarse) {
    return coarse == 0 ? 0.0 : std::pow(10.0, static_cast<double>(coarse - 1) / kCoarsePerDecade);
  }

  void add(double value) {
    ++count_;
    if (value > max_) max_ = value;
    ++buckets_[static_cast<std::size_t>(bucket_of(value))];
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
