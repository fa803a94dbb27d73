// cyclictest (Debian's rt-tests) as the reference of `ncd bench latency`: run it on one thread
// with the same period, read its histogram file, and turn it into percentiles.
//
// The histogram file (--histfile, rt-tests 2.x) has one line per microsecond of latency, the
// latency truncated to whole µs, one count column per measuring thread, then a summary:
//
//   # Histogram
//   000016 000012          <- 12 wake-ups between 16 and 17 µs late
//   ...
//   # Total: 000000500     <- samples inside the histogram (overflows not included)
//   # Min Latencies: 00016
//   # Avg Latencies: 00020
//   # Max Latencies: 00087 <- exact, whole µs
//   # Histogram Overflows: 00000   <- samples at or above the histogram's limit (-h)
//
// Percentiles take the overflows as samples above every bucket: a percentile that falls among
// them is reported as the maximum (an upper bound) and flagged.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "app/latency_report.hpp"

namespace ncd::app {

struct CyclictestHistogram {
  std::vector<std::int64_t> count_per_us;  // [i]: samples with latency in [i, i+1) µs
  std::int64_t overflows = 0;
  double max_us = 0.0;  // "# Max Latencies" (the last non-empty bucket if absent)
  std::int64_t samples() const;
};

// Parses the text of a --histfile; throws std::runtime_error naming the line when malformed or
// when "# Total" disagrees with the buckets.
CyclictestHistogram parse_cyclictest_histogram(std::string_view text);

struct CyclictestPercentiles {
  LatencyPercentiles us;
  bool overflowed = false;  // some percentile lay beyond the histogram: reported as the max
};
// Percentiles in whole µs as cyclictest counts them (see the top of this file).
CyclictestPercentiles cyclictest_percentiles(const CyclictestHistogram& histogram);

struct CyclictestOptions {
  std::string executable = "cyclictest";  // looked up on PATH
  int interval_us = 4000;
  int seconds = 1;
  int priority = 80;            // SCHED_FIFO priority
  int histogram_max_us = 1000;  // -h
};

struct CyclictestRun {
  bool ok = false;
  std::string reason;              // why there is no result (when !ok)
  std::string command;             // the command line that gave the result (or the last tried)
  std::vector<std::string> notes;  // fallbacks taken, power-management settings it made
  CyclictestHistogram histogram;
  CyclictestPercentiles percentiles;
};

// Runs `cyclictest -m -q -t1 -p<prio> -i<interval> -D<seconds>s -h<max> --histfile=F`; when it
// fails, once more without -m (locked memory refused), saying so in notes. rt-tests 2.40 will
// not run at all without the right to real-time scheduling: then !ok, with its message.
CyclictestRun run_cyclictest(const CyclictestOptions& options);

}  // namespace ncd::app
