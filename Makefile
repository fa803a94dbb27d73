# Quick start: `make demo` and `make test`. Both install missing Debian packages first.
JOBS ?= $(shell nproc)
NCD := build/release/app/ncd

.PHONY: all deps deps-build release debug demo test test-release test-debug test-fuzz fuzz fuzz-build soak-cell format \
	format-check bench soak clean install uninstall

# `make install [PREFIX=/usr/local] [DESTDIR=]`: the binary, the systemd unit (its paths set to
# PREFIX), the sysusers entry of the user `ncd`, the example configs (an existing
# /etc/ncd/serve.toml is kept) and the documentation. With an empty DESTDIR, as root, the user is
# created and systemd reloaded. See docs/hardening.md, "Deployment".
PREFIX ?= /usr/local
SYSCONFDIR ?= /etc
UNITDIR ?= $(SYSCONFDIR)/systemd/system
SYSUSERSDIR ?= /usr/lib/sysusers.d
DOCDIR ?= $(PREFIX)/share/doc/ncd
# What install builds first; `make install INSTALL_NEEDS= NCD=path/to/ncd` installs a binary
# already built (tests/install/make_install_test.sh).
INSTALL_NEEDS ?= release

all: release

deps:
	@scripts/install-deps.sh

# Only what building `ncd` needs: the demo does not wait for the test tools (chromium, clang-14).
deps-build:
	@scripts/install-deps.sh --build

release: deps
	@cmake --preset release >/dev/null
	@cmake --build --preset release -j $(JOBS)

debug: deps
	@cmake --preset debug >/dev/null
	@cmake --build --preset debug -j $(JOBS)

# The demo builds only the `ncd` executable; the tests and benchmarks build under `make test`.
demo: deps-build
	@cmake --preset release >/dev/null
	@cmake --build --preset release -j $(JOBS) --target ncd
	@scripts/demo.sh $(NCD)

# The fuzz corpus (scripts/fuzz.sh corpus 2000, what `make test-fuzz` runs alone) is a part of the
# sanitizer suite: the tests Fuzz.<name>Corpus of the debug tree (tests/fuzz/CMakeLists.txt).
test: format-check test-release test-debug

# The tests that wait (streaming at a baud rate, servers, a browser) run beside the ones that
# compute: ctest -j 4×JOBS with the resource file build/<tree>/tests/cpus.json, four slots a core,
# so that no more computing tests run at once than there are cores (tests/CMakeLists.txt,
# docs/testing.md "Fourth pass"). `make test CTEST_OVERLAP=0` runs plain ctest -j JOBS.
CTEST_OVERLAP ?= 1
ctest_jobs = $(if $(filter 1,$(CTEST_OVERLAP)),-j $(shell expr 4 \* $(JOBS)) \
	--resource-spec-file $(CURDIR)/build/$(1)/tests/cpus.json,-j $(JOBS))

test-release: release
	ctest --preset release $(call ctest_jobs,release)

test-debug: debug
	ctest --preset debug $(call ctest_jobs,debug)

# libFuzzer harnesses of tests/fuzz (docs/input-ranges.md): `make fuzz` runs each FUZZ_SECONDS.
# They build in the sanitizer tree (build/debug, clang-14) with the test suite: after `make
# test-debug`, fuzz-build has nothing left to do (docs/testing.md).
FUZZ_SECONDS ?= 60
fuzz-build: deps
	@cmake --preset debug >/dev/null
	@cmake --build --preset fuzz -j $(JOBS)

fuzz: fuzz-build
	scripts/fuzz.sh run $(FUZZ_SECONDS)

test-fuzz: fuzz-build
	scripts/fuzz.sh corpus 2000

bench: release
	build/release/bench/ncd_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

# The planner's random-program property suite at length (the Release suite runs 200).
soak: release
	NCD_PROPERTY_PROGRAMS=$${NCD_PROPERTY_PROGRAMS:-5000} build/release/tests/test_motion --gtest_filter='Property.*'

# The cell page with 20 `ncd serve` on one mosquitto, a headless Chromium showing them: latency,
# CPU, messages per second and a broker restart (docs/web-dashboard.md, "The cell page").
soak-cell: release
	NCD_CELL_MACHINES=$${NCD_CELL_MACHINES:-20} NCD_CELL_SECONDS=$${NCD_CELL_SECONDS:-60} \
	    build/release/tests/test_web --gtest_also_run_disabled_tests \
	    --gtest_filter='CellPage.DISABLED_SoakTwentyMachines'

format:
	@git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

format-check: deps
	@files=$$(git ls-files '*.cpp' '*.hpp'); \
	if [ -n "$$files" ]; then clang-format --dry-run -Werror $$files; fi

install: $(INSTALL_NEEDS)
	install -D -m 0755 $(NCD) $(DESTDIR)$(PREFIX)/bin/ncd
	install -d $(DESTDIR)$(UNITDIR) $(DESTDIR)$(SYSCONFDIR)/ncd $(DESTDIR)$(DOCDIR)/docs
	sed -e 's|/usr/local/bin/ncd|$(PREFIX)/bin/ncd|' \
	    -e 's|/usr/local/share/doc/ncd|$(DOCDIR)|' \
	    -e 's|/etc/ncd/|$(SYSCONFDIR)/ncd/|' deploy/ncd.service > $(DESTDIR)$(UNITDIR)/ncd.service
	chmod 0644 $(DESTDIR)$(UNITDIR)/ncd.service
	install -D -m 0644 deploy/ncd.sysusers.conf $(DESTDIR)$(SYSUSERSDIR)/ncd.conf
	install -m 0644 config/serve.example.toml config/machine.example.toml \
	    $(DESTDIR)$(SYSCONFDIR)/ncd/
	[ -e $(DESTDIR)$(SYSCONFDIR)/ncd/serve.toml ] || \
	    install -m 0644 config/serve.example.toml $(DESTDIR)$(SYSCONFDIR)/ncd/serve.toml
	install -m 0644 README.md $(DESTDIR)$(DOCDIR)/
	install -m 0644 docs/*.md $(DESTDIR)$(DOCDIR)/docs/
	@if [ -z "$(DESTDIR)" ] && [ "$$(id -u)" = 0 ]; then \
	    systemd-sysusers $(SYSUSERSDIR)/ncd.conf 2>/dev/null || \
	    { getent passwd ncd >/dev/null || useradd --system --home-dir /var/lib/ncd \
	        --shell /usr/sbin/nologin --groups dialout ncd; }; \
	    systemctl daemon-reload 2>/dev/null || true; \
	fi

# Removes what install put there; keeps serve.toml (the user's configuration).
uninstall:
	rm -f $(DESTDIR)$(PREFIX)/bin/ncd $(DESTDIR)$(UNITDIR)/ncd.service \
	    $(DESTDIR)$(SYSUSERSDIR)/ncd.conf $(DESTDIR)$(SYSCONFDIR)/ncd/serve.example.toml \
	    $(DESTDIR)$(SYSCONFDIR)/ncd/machine.example.toml
	rm -rf $(DESTDIR)$(DOCDIR)

clean:
	rm -rf build out
