#!/usr/bin/env bash
# Installs the Debian 12 packages ncd needs to build, test and run, if any are missing;
# with --build, only those that building the `ncd` executable needs (`make demo`).
# Run as root (or with sudo available); prints what it installs and does nothing when all are there.
set -euo pipefail
# What building the `ncd` executable needs (`make demo` installs only these: `--build`).
build_pkgs=(build-essential cmake ninja-build pkg-config
      libeigen3-dev libboost-dev libserial-dev libcli11-dev nlohmann-json3-dev libtoml11-dev
      libfmt-dev libssl-dev
      zlib1g-dev                    # zlib: the PNG writer of ncd simulate
      libpaho-mqttpp-dev libpaho-mqtt-dev)  # MQTT: ncd serve [mqtt]
# What the tests, benchmarks and fuzzers need besides (`make test`, `make bench`, `make fuzz`).
test_pkgs=(clang-format libgtest-dev libgmock-dev libbenchmark-dev libspdlog-dev rt-tests
      mosquitto mosquitto-clients   # a real broker for tests/api and ncd bench's MQTT phase
      openssl                       # the test certificates of the TLS tests (tests/api, tests/web)
      clang-14 libclang-rt-14-dev   # clang-14, libclang-rt: the libFuzzer harnesses (make fuzz)
      chromium chromium-driver)     # the web dashboard's browser test (tests/web)
if [ "${1:-}" = "--build" ]; then
  shift
  pkgs=("${build_pkgs[@]}" "$@")
else
  pkgs=("${build_pkgs[@]}" "${test_pkgs[@]}" "$@")  # more a caller asks for (install-judges.sh)
fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "ncd: installing missing packages: ${missing[*]}"
if [ "$(id -u)" -eq 0 ]; then
  as_root=()
elif command -v sudo >/dev/null 2>&1; then
  as_root=(sudo)
else
  echo "ncd: not root and no sudo; install them with: apt-get install ${missing[*]}" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -qq
"${as_root[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
