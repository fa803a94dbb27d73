#!/usr/bin/env bash
# Runs the libFuzzer harnesses of build/debug (the debug preset, clang-14, which builds them beside
# the sanitizer test suite; `make fuzz-build` builds only them; docs/input-ranges.md).
#   scripts/fuzz.sh corpus [RUNS]      every seed of tests/fuzz/corpus/<name>/, then mutations up
#                                      to RUNS inputs each (default 2000) from a fixed seed, so
#                                      that the same code gives the same result; what `make test`
#                                      runs
#   scripts/fuzz.sh run [SECONDS]      SECONDS of fuzzing each (default 60, FUZZ_SECONDS in make),
#                                      new inputs kept in build/debug/fuzz/corpus/<name>/
#   FUZZ_HARNESS=pipeline scripts/fuzz.sh …   only that harness (default: every one)
#   FUZZ_TREE=DIR scripts/fuzz.sh …            the harnesses of the build tree DIR (default
#                                              build/debug; the ctest entries Fuzz.<name>Corpus
#                                              of the debug tree pass their own)
# Exits non-zero on the first finding (a crash, a sanitizer report, an escaped exception, a
# timeout of 10 s on one input, more than 2 GB of memory); the input is saved as
# build/debug/fuzz/artifacts/<name>-crash-… and can be replayed with
# build/debug/tests/fuzz/ncd_fuzz_<name> FILE.
# The pipeline harness walks a whole job per input (seconds under the sanitizers, flowsnake.ngc
# about 20 s): its timeout is 120 s, and `corpus` gives it its seeds and 100 mutated inputs
# (PIPELINE_RUNS sets the mutations) instead of 2000.
set -euo pipefail
mode=${1:-corpus}
root=$(cd "$(dirname "$0")/.." && pwd)
tree=${FUZZ_TREE:-$root/build/debug}
bin=$tree/tests/fuzz
out=$tree/fuzz
case $mode in
  corpus) limit=(-seed=1 -runs="${2:-2000}") ;;
  run) limit=(-max_total_time="${2:-60}") ;;
  *) echo "usage: $0 corpus|run [SECONDS]" >&2; exit 2 ;;
esac
shopt -s nullglob
harnesses=("$root"/tests/fuzz/*_fuzz.cpp)
if [ ${#harnesses[@]} -eq 0 ]; then echo "no harness in tests/fuzz" >&2; exit 1; fi
mkdir -p "$out/artifacts"
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
for src in "${harnesses[@]}"; do
  stem=$(basename "$src" .cpp)
  name=${stem%_fuzz}
  if [ -n "${FUZZ_HARNESS:-}" ] && [ "$name" != "$FUZZ_HARNESS" ]; then continue; fi
  exe=$bin/ncd_fuzz_$name
  seeds=$root/tests/fuzz/corpus/$name
  if [ ! -x "$exe" ]; then echo "$exe is missing: build the debug preset first (make fuzz-build)" >&2; exit 1; fi
  if [ ! -d "$seeds" ]; then echo "$seeds is missing: every harness needs a seed corpus" >&2; exit 1; fi
  if [ "$mode" = run ]; then
    work=$out/corpus/$name
  else
    work=$scratch/$name
  fi
  mkdir -p "$work"
  timeout=10
  args=("${limit[@]}")
  if [ "$name" = pipeline ]; then
    timeout=120
    # libFuzzer's -runs counts the seeds too.
    if [ "$mode" = corpus ]; then args=(-seed=1 -runs=$(($(ls "$seeds" | wc -l) + ${PIPELINE_RUNS:-100}))); fi
  fi
  echo "fuzz $name: ${args[*]} from $(ls "$seeds" | wc -l) seeds"
  # The harness runs in the scratch directory: files the fuzzer names (a service config's
  # "machine") are looked up there, not in the source tree.
  (cd "$scratch" && "$exe" "${args[@]}" -timeout=$timeout -rss_limit_mb=2048 \
      -print_final_stats=0 -artifact_prefix="$out/artifacts/$name-" \
      "$work" "$seeds" 2>"$scratch/$name.log") || {
    echo "fuzz $name FAILED; the log follows, the input is in build/debug/fuzz/artifacts/" >&2
    tail -n 60 "$scratch/$name.log" >&2
    exit 1
  }
  grep -E "^#[0-9]+ +DONE|Done [0-9]+ runs" "$scratch/$name.log" | tail -n 1 || true
done
