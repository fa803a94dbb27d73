// Latency report pieces of `ncd bench latency`; the rules are in latency_report.hpp.
#include "app/latency_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>

#include "core/number_text.hpp"

namespace ncd::app {

std::string format_us(double us) {
  const double a = std::fabs(us);
  const int decimals = a >= 100.0 ? 0 : a >= 10.0 ? 1 : a >= 1.0 ? 2 : 3;
  return text::fixed(us, decimals);
}

nlohmann::ordered_json percentiles_json(const LatencyPercentiles& p) {
  return {{"p50", p.p50_us}, {"p99", p.p99_us}, {"p999", p.p999_us}, {"max", p.max_us}};
}

LatencyPercentiles percentiles_us_from_ns(const LogHistogram& histogram_ns) {
  return {histogram_ns.quantile(0.5) * 1e-3, histogram_ns.quantile(0.99) * 1e-3,
          histogram_ns.quantile(0.999) * 1e-3, histogram_ns.max() * 1e-3};
}

void merge_into(LogHistogram& dst, const LogHistogram& src) {
  if (src.count() == 0) return;
  // A value inside each bucket (its geometric centre, below 1 for the first); the bucket that
  // holds the maximum gets the maximum itself once and values not above it for the rest.
  const auto& b = src.buckets();
  LogHistogram probe;
  probe.add(src.max());
  const auto& pb = probe.buckets();
  const auto max_bucket = static_cast<std::size_t>(
      std::find_if(pb.begin(), pb.end(), [](std::int64_t n) { return n > 0; }) - pb.begin());
  for (std::size_t i = 0; i < b.size(); ++i) {
    if (b[i] == 0) continue;
    double inside = i == 0 ? 0.5
                           : std::pow(10.0, (static_cast<double>(i) - 0.5) /
                                                static_cast<double>(LogHistogram::kPerDecade));
    std::int64_t n = b[i];
    if (i == max_bucket) {
      dst.add(src.max());
      inside = std::min(inside, src.max());
      --n;
    }
    for (std::int64_t k = 0; k < n; ++k) dst.add(inside);
  }
}

void add_stats(motion::CycleStats& sum, const motion::CycleStats& s) {
  merge_into(sum.lateness_ns, s.lateness_ns);
  merge_into(sum.compute_ns, s.compute_ns);
  sum.periods += s.periods;
  sum.late_wakeups += s.late_wakeups;
  sum.caught_up += s.caught_up;
  sum.overruns += s.overruns;
  sum.setpoints_lost += s.setpoints_lost;
}

std::vector<HistogramBin> histogram_bins_us(const LogHistogram& histogram_ns, int per_decade) {
  if (per_decade <= 0 || LogHistogram::kPerDecade % per_decade != 0) {
    throw std::invalid_argument("histogram_bins_us: per_decade must divide " +
                                std::to_string(LogHistogram::kPerDecade));
  }
  const auto group = static_cast<std::size_t>(LogHistogram::kPerDecade / per_decade);
  const auto& b = histogram_ns.buckets();
  // Bin 0: values below 1 ns; bin d >= 1 gathers LogHistogram buckets 1 + (d-1) group ..
  // d group, values in [10^((d-1)/per_decade), 10^(d/per_decade)) ns.
  std::vector<std::int64_t> counts(1 + (b.size() - 1 + group - 1) / group, 0);
  counts[0] = b[0];
  for (std::size_t i = 1; i < b.size(); ++i) counts[1 + (i - 1) / group] += b[i];
  const auto edge_us = [&](std::size_t d) {
    return 1e-3 * std::pow(10.0, static_cast<double>(d) / static_cast<double>(per_decade));
  };
  std::vector<HistogramBin> bins;
  for (std::size_t d = 0; d < counts.size(); ++d) {
    if (counts[d] == 0) continue;
    bins.push_back({d == 0 ? 0.0 : edge_us(d - 1), edge_us(d), counts[d]});
  }
  return bins;
}

std::string format_histogram_us(const LogHistogram& histogram_ns, int per_decade, int bar_width) {
  const std::vector<HistogramBin> bins = histogram_bins_us(histogram_ns, per_decade);
  std::int64_t most = 0;
  for (const HistogramBin& b : bins) most = std::max(most, b.count);
  std::string out;
  for (const HistogramBin& b : bins) {
    const auto len =
        std::max<long>(1, std::lround(static_cast<double>(bar_width) *
                                      static_cast<double>(b.count) / static_cast<double>(most)));
    char line[256];
    std::snprintf(line, sizeof line, "  %8s - %8s us |%-*s| %lld\n", format_us(b.from_us).c_str(),
                  format_us(b.to_us).c_str(), bar_width,
                  std::string(static_cast<std::size_t>(len), '#').c_str(),
                  static_cast<long long>(b.count));
    out += line;
  }
  return out;
}

std::string format_latency_table(const std::vector<LatencyRow>& rows) {
  char line[256];
  std::snprintf(line, sizeof line, "%-14s %10s %10s %10s %10s\n", "latency (us)", "p50", "p99",
                "p99.9", "max");
  std::string out = line;
  for (const LatencyRow& r : rows) {
    std::snprintf(line, sizeof line, "%-14s %10s %10s %10s %10s\n", r.name.c_str(),
                  format_us(r.us.p50_us).c_str(), format_us(r.us.p99_us).c_str(),
                  format_us(r.us.p999_us).c_str(), format_us(r.us.max_us).c_str());
    out += line;
  }
  return out;
}

P99Verdict p99_verdict(double ncd_p99_us, double reference_p99_us, double limit) {
  P99Verdict v;
  v.limit = limit;
  char line[256];
  if (!(reference_p99_us > 0.0)) {
    std::snprintf(line, sizeof line, "ncd p99 / cyclictest p99: no ratio (cyclictest p99 is %s us)",
                  format_us(reference_p99_us).c_str());
    v.line = line;
    return v;
  }
  v.ratio = ncd_p99_us / reference_p99_us;
  v.within = *v.ratio <= limit;
  std::snprintf(line, sizeof line, "ncd p99 / cyclictest p99 = %.2f (limit %.2g): %s", *v.ratio,
                limit, v.within ? "within the limit" : "above the limit");
  v.line = line;
  return v;
}

}  // namespace ncd::app
