# Quick start: `make demo` and `make test`. Both install missing Debian packages first.
JOBS ?= $(shell nproc)
NCD := build/release/app/ncd

.PHONY: all deps release debug demo test test-release test-debug test-fuzz fuzz fuzz-build format \
	format-check bench clean

all: release

deps:
	@scripts/install-deps.sh

release: deps
	@cmake --preset release >/dev/null
	@cmake --build --preset release -j $(JOBS)

debug: deps
	@cmake --preset debug >/dev/null
	@cmake --build --preset debug -j $(JOBS)

demo: release
	@scripts/demo.sh $(NCD)

test: format-check test-release test-debug test-fuzz

test-release: release
	ctest --preset release -j $(JOBS)

test-debug: debug
	ctest --preset debug -j $(JOBS)

# libFuzzer harnesses of tests/fuzz (docs/input-ranges.md): `make fuzz` runs each FUZZ_SECONDS.
FUZZ_SECONDS ?= 60
fuzz-build: deps
	@cmake --preset fuzz >/dev/null
	@cmake --build --preset fuzz -j $(JOBS)

fuzz: fuzz-build
	scripts/fuzz.sh run $(FUZZ_SECONDS)

test-fuzz: fuzz-build
	scripts/fuzz.sh corpus 2000

bench: release
	build/release/bench/ncd_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

format:
	@git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

format-check: deps
	@files=$$(git ls-files '*.cpp' '*.hpp'); \
	if [ -n "$$files" ]; then clang-format --dry-run -Werror $$files; fi

clean:
	rm -rf build out
