#!/usr/bin/env bash
# `make install` and `make uninstall` into a DESTDIR, on the binary already built (no rebuild:
# INSTALL_NEEDS= NCD=...). Checks, for PREFIX=/usr/local and for PREFIX=/opt/ncd:
#   - every file in place, with its mode; the binary identical to the built one;
#   - the unit's paths point into PREFIX, and each file the unit names exists in the DESTDIR;
#   - the sysusers entry, read by systemd-sysusers itself (--root), creates the user the unit
#     runs as, in the group dialout;
#   - an existing serve.toml is kept by a second install;
#   - `make uninstall` removes what install put there and nothing else (files of other packages
#     in the same folders stay; serve.toml, the user's configuration, stays).
# Usage: make_install_test.sh SOURCE_DIR NCD_BINARY
set -euo pipefail
src=$1
bin=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}
expect_file() {  # path mode
  if [[ ! -f $1 ]]; then
    fail "$1 was not installed"
  elif [[ $(stat -c %a "$1") != "$2" ]]; then
    fail "$1 has mode $(stat -c %a "$1"), not $2"
  fi
}

for prefix in /usr/local /opt/ncd; do
  dest=$tmp/root${prefix//\//_}
  mkdir -p "$dest"
  # Files of other packages in the folders ncd installs into: uninstall must leave them.
  mkdir -p "$dest$prefix/bin" "$dest/etc/systemd/system" "$dest/usr/lib/sysusers.d" \
    "$dest$prefix/share/doc/other"
  echo other >"$dest$prefix/bin/other"
  echo other >"$dest/etc/systemd/system/other.service"
  echo other >"$dest/usr/lib/sysusers.d/other.conf"
  echo other >"$dest$prefix/share/doc/other/README"
  make -s -C "$src" install DESTDIR="$dest" PREFIX="$prefix" INSTALL_NEEDS= NCD="$bin" \
    >"$tmp/install.log" 2>&1 || { cat "$tmp/install.log" >&2; fail "make install PREFIX=$prefix failed"; continue; }

  expect_file "$dest$prefix/bin/ncd" 755
  cmp -s "$bin" "$dest$prefix/bin/ncd" || fail "$prefix/bin/ncd differs from $bin"
  unit=$dest/etc/systemd/system/ncd.service
  expect_file "$unit" 644
  expect_file "$dest/usr/lib/sysusers.d/ncd.conf" 644
  cmp -s "$src/deploy/ncd.sysusers.conf" "$dest/usr/lib/sysusers.d/ncd.conf" ||
    fail "the sysusers entry differs from deploy/ncd.sysusers.conf"
  for f in serve.example.toml machine.example.toml serve.toml; do
    expect_file "$dest/etc/ncd/$f" 644
  done
  cmp -s "$src/config/serve.example.toml" "$dest/etc/ncd/serve.toml" ||
    fail "a first install's serve.toml is not the example"
  docdir=$dest$prefix/share/doc/ncd
  # As in the repository (docs/README.md links to ../README.md).
  expect_file "$docdir/README.md" 644
  cmp -s "$src/README.md" "$docdir/README.md" || fail "the installed README.md is not the top one"
  for f in "$src"/docs/*.md; do
    expect_file "$docdir/docs/$(basename "$f")" 644
  done

  # The unit's paths: into PREFIX, and each file it names is there.
  exec_start=$(sed -n 's/^ExecStart=//p' "$unit")
  [[ $exec_start == "$prefix/bin/ncd serve --config /etc/ncd/serve.toml" ]] ||
    fail "ExecStart is '$exec_start' for PREFIX=$prefix"
  for path in $(grep -o '/[^ ]*' <<<"$exec_start"); do
    [[ -e $dest$path ]] || fail "the unit names $path, which install did not put there"
  done
  doc=$(sed -n 's/^Documentation=file://p' "$unit")
  [[ $doc == "$prefix/share/doc/ncd/"* && -f $dest$doc ]] ||
    fail "Documentation=$doc is not an installed file under $prefix"
  if [[ $prefix != /usr/local ]] && grep -v '^#' "$unit" | grep -n '/usr/local'; then
    fail "the unit still names /usr/local with PREFIX=$prefix"
  fi
  # Only the install lines differ from the unit in the repository.
  diff <(sed "s|$prefix|/usr/local|g" "$unit") "$src/deploy/ncd.service" >/dev/null ||
    fail "the installed unit differs from deploy/ncd.service by more than PREFIX"

  # The sysusers entry as systemd reads it: the unit's User and Group exist, in dialout.
  user=$(sed -n 's/^User=//p' "$unit")
  group=$(sed -n 's/^Group=//p' "$unit")
  if command -v systemd-sysusers >/dev/null; then
    sys=$tmp/sysroot
    rm -rf "$sys" && mkdir -p "$sys/etc"
    printf 'root:x:0:0::/root:/bin/sh\n' >"$sys/etc/passwd"
    printf 'root:x:0:\ndialout:x:20:\n' >"$sys/etc/group"
    systemd-sysusers --root="$sys" "$dest/usr/lib/sysusers.d/ncd.conf" >"$tmp/sysusers.log" 2>&1 ||
      { cat "$tmp/sysusers.log" >&2; fail "systemd-sysusers refused the entry"; }
    grep -q "^$user:" "$sys/etc/passwd" || fail "the sysusers entry creates no user '$user'"
    grep -q "^$group:" "$sys/etc/group" || fail "the sysusers entry creates no group '$group'"
    grep -Eq "^dialout:x:20:(.*,)?$user(,|$)" "$sys/etc/group" ||
      fail "the user '$user' is not in dialout: $(grep '^dialout' "$sys/etc/group")"
  else
    echo "systemd-sysusers is not installed: the entry's syntax is not checked" >&2
  fi

  # A second install keeps an existing serve.toml.
  echo '# edited by the user' >>"$dest/etc/ncd/serve.toml"
  cp "$dest/etc/ncd/serve.toml" "$tmp/serve.edited"
  make -s -C "$src" install DESTDIR="$dest" PREFIX="$prefix" INSTALL_NEEDS= NCD="$bin" \
    >"$tmp/install.log" 2>&1 || fail "a second make install failed"
  cmp -s "$tmp/serve.edited" "$dest/etc/ncd/serve.toml" || fail "a second install replaced serve.toml"

  # Uninstall: what install added goes, nothing else.
  make -s -C "$src" uninstall DESTDIR="$dest" PREFIX="$prefix" >"$tmp/uninstall.log" 2>&1 ||
    { cat "$tmp/uninstall.log" >&2; fail "make uninstall failed"; }
  left=$(cd "$dest" && find . -type f | sort | tr '\n' ' ')
  want=$(printf '%s\n' ".$prefix/bin/other" ./etc/systemd/system/other.service \
    ./usr/lib/sysusers.d/other.conf ".$prefix/share/doc/other/README" ./etc/ncd/serve.toml |
    sort | tr '\n' ' ')
  [[ $left == "$want" ]] || fail "after uninstall (PREFIX=$prefix) the files are: $left; expected: $want"
  echo "PREFIX=$prefix: installed, serve.toml kept, uninstalled ($(wc -w <<<"$want") files left, all foreign or the user's)"
done

if ((failures > 0)); then
  echo "$failures failure(s)" >&2
  exit 1
fi
echo "make install / uninstall: all checks passed"
