// RS-274/NGC interpreter speed (docs/ngc-interpreter.md): a 40 000-line program of dense G1
// moves (the size of the program LinuxCNC's rs274 reads in 0.11 s of CPU) against a baseline
// that only splits the text into lines and words, and an expression- and loop-heavy program.
#include <benchmark/benchmark.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "gcode/ngc/interpreter.hpp"
#include "gcode/program.hpp"

namespace ncd::toolpath {
namespace {

// 40 000 lines of "G1 X… Y…" around a spiral, about 0.7 MB.
std::string dense_program(int lines) {
  std::string text = "G21 G90 G17 G94 F1200\nG0 X0 Y0 Z0\n";
  char buf[64];
  for (int i = 0; i < lines; ++i) {
    const double t = i * 0.01;
    const double r = 10.0 + 0.001 * i;
    std::snprintf(buf, sizeof buf, "G1 X%.3f Y%.3f\n", r * std::cos(t), r * std::sin(t));
    text += buf;
  }
  text += "M2\n";
  return text;
}

// A while loop computing each point with trigonometry and arithmetic, nested in a repeat.
std::string loop_program(int points) {
  return "G21 G90 F600\nG0 X0 Y0 Z0\n#<n> = " + std::to_string(points) +
         "\n#1 = 0\n"
         "o10 while [#1 LT #<n>]\n"
         "  #2 = [#1 * 360 / #<n>]\n"
         "  #3 = [[10 + #1 MOD 7] * COS[#2] + SQRT[ABS[SIN[#2 * 3]]] ** 2]\n"
         "  #4 = [[10 + #1 MOD 7] * SIN[#2] - [#1 GT 100 AND #1 LT 200]]\n"
         "  G1 X#3 Y#4 Z[-0.001 * #1]\n"
         "  #1 = [#1 + 1]\n"
         "o10 endwhile\nM2\n";
}

// Baseline: split into lines, then into letter + number words (no semantics).
std::size_t split_words(const std::string& text) {
  std::size_t words = 0;
  double sum = 0.0;
  const char* p = text.data();
  const char* end = p + text.size();
  while (p < end) {
    const char* nl =
        static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
    if (!nl) nl = end;
    const char* q = p;
    while (q < nl) {
      if (*q >= 'A' && *q <= 'Z') {
        ++q;
        double v = 0.0;
        const auto r = std::from_chars(q, nl, v);
        q = r.ptr == q ? q + 1 : r.ptr;
        sum += v;
        ++words;
      } else {
        ++q;
      }
    }
    p = nl + 1;
  }
  benchmark::DoNotOptimize(sum);
  return words;
}

void BM_NgcDenseG1(benchmark::State& state) {
  const std::string text = dense_program(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    Program p = interpret_ngc(text, "dense.ngc");
    benchmark::DoNotOptimize(p.steps.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(text.size()));
  state.counters["lines_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * static_cast<double>(state.range(0)),
      benchmark::Counter::kIsRate);
}
BENCHMARK(BM_NgcDenseG1)->Arg(40000)->Unit(benchmark::kMillisecond);

void BM_NgcDenseG1ToPath(benchmark::State& state) {
  const std::string text = dense_program(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    const Path path = to_path(interpret_ngc(text, "dense.ngc"));
    benchmark::DoNotOptimize(path.segments.data());
  }
}
BENCHMARK(BM_NgcDenseG1ToPath)->Arg(40000)->Unit(benchmark::kMillisecond);

void BM_LineSplitBaseline(benchmark::State& state) {
  const std::string text = dense_program(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(split_words(text));
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(text.size()));
}
BENCHMARK(BM_LineSplitBaseline)->Arg(40000)->Unit(benchmark::kMillisecond);

void BM_NgcExpressionLoop(benchmark::State& state) {
  const std::string text = loop_program(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    Program p = interpret_ngc(text, "loop.ngc");
    benchmark::DoNotOptimize(p.steps.data());
  }
  state.counters["iterations_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * static_cast<double>(state.range(0)),
      benchmark::Counter::kIsRate);
}
BENCHMARK(BM_NgcExpressionLoop)->Arg(10000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ncd::toolpath
