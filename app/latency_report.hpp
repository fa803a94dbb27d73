// The numbers and text of `ncd bench latency`: wake-up lateness percentiles from a LogHistogram
// (ncd's cycle) or from cyclictest's histogram, a text histogram on log buckets, and the table
// that puts ncd beside cyclictest with the ratio of their p99 against a limit.
//
//   latency (us)        p50       p99     p99.9       max
//   ncd                12.3      45.6      78.9     123.0
//   cyclictest         10.0      30.0      50.0      87.0
//   ncd p99 / cyclictest p99 = 1.52 (limit 1.5): above the limit
//
// Percentile rule, for both sources: the value below which ceil(q N) of the N samples lie.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/histogram.hpp"
#include "motion/cycle.hpp"

namespace ncd::app {

struct LatencyPercentiles {
  double p50_us = 0.0, p99_us = 0.0, p999_us = 0.0, max_us = 0.0;
};

// {p50, p99, p999, max} in µs, the shape of every lateness in the benchmarks' JSON.
nlohmann::ordered_json percentiles_json(const LatencyPercentiles& p);

// Percentiles of a histogram of nanoseconds, in µs (LogHistogram::quantile: within 3.7 %).
LatencyPercentiles percentiles_us_from_ns(const LogHistogram& histogram_ns);

// Adds every sample of src into dst: bucket counts and count exact, the maximum exact.
void merge_into(LogHistogram& dst, const LogHistogram& src);

// Adds one cycle's statistics to the sum of a run of several jobs or phases.
void add_stats(motion::CycleStats& sum, const motion::CycleStats& s);

// The non-empty buckets of a histogram of nanoseconds, regrouped to `per_decade` buckets per
// decade (a divisor of LogHistogram::kPerDecade), in µs: [from_us, to_us); the first bin of
// LogHistogram (below 1 ns) starts at 0.
struct HistogramBin {
  double from_us = 0.0, to_us = 0.0;
  std::int64_t count = 0;
};
std::vector<HistogramBin> histogram_bins_us(const LogHistogram& histogram_ns, int per_decade = 8);

// Those bins one line each, "  from - to us |####   | count"; bars linear in the count, at
// least one '#' for a non-empty bin.
std::string format_histogram_us(const LogHistogram& histogram_ns, int per_decade = 8,
                                int bar_width = 40);

struct LatencyRow {
  std::string name;
  LatencyPercentiles us;
};

// The table of rows: a header and one line per row, p50 p99 p99.9 max in µs.
std::string format_latency_table(const std::vector<LatencyRow>& rows);

// ncd p99 over the reference p99 against a limit; no ratio when the reference p99 is not > 0.
struct P99Verdict {
  std::optional<double> ratio;
  double limit = 1.5;
  bool within = false;  // ratio <= limit
  std::string line;     // one line saying the ratio, the limit and the verdict (or why none)
};
P99Verdict p99_verdict(double ncd_p99_us, double reference_p99_us, double limit = 1.5);

// A number in µs with three significant digits and no exponent ("0.512", "12.3", "1234").
std::string format_us(double us);

}  // namespace ncd::app
