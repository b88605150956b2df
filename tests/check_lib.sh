#!/usr/bin/env bash
# Shared by the install tests (install_test.sh, make_install_test.sh,
# deb_install_test.sh): one "ok: ..." / "FAIL: ..." / "skip: ..." line per
# check, then "runtime: N s" and "N passed, M failed"; finish exits 1 on any
# failure. Source it after setting up traps; it starts the clock.
start=$SECONDS
passed=0
failed=0
ok() { echo "ok: $*"; passed=$((passed + 1)); }
fail() { echo "FAIL: $*"; failed=$((failed + 1)); }
skip() { echo "skip: $*"; }
finish() {
  echo "runtime: $((SECONDS - start)) s"
  echo "$passed passed, $failed failed"
  [[ $failed -eq 0 ]] || exit 1
  exit 0
}
# The last lines of a log on one line, for a FAIL message.
tail_of() { tail -n "${2:-5}" "$1" | tr '\n' '|' | head -c 800; }
