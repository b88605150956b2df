# Helpers shared by the end-to-end CLI test scripts (sourced, not run).
# A script sources this file, calls cli_init NAME (checks MVKP and SAMPLES,
# sets PY, the scratch directory T and the counters passed / failed / known),
# runs its checks, and ends with cli_finish.

cli_init() {
  : "${MVKP:?set MVKP to the mvkp binary}"
  : "${SAMPLES:?set SAMPLES to the samples directory}"
  PY=/usr/bin/python3
  T=$(mktemp -d "${TMPDIR:-/tmp}/mvkp_$1_test.XXXXXX") || exit 1
  trap 'rm -rf "$T"' EXIT
  start=$SECONDS
  passed=0
  failed=0
  known=0
}

# Prints the runtime and the counts; exits 1 if any check failed.
cli_finish() {
  echo "runtime: $((SECONDS - start)) s${1:+; $1}"
  echo "$passed passed, $failed failed"
  [[ $failed -eq 0 ]] || exit 1
}

ok() { echo "ok: $*"; passed=$((passed + 1)); }
# A failure; under known_bug it is reported as KNOWN-BUG and does not fail the suite.
fail() {
  if [[ -n ${KNOWN:-} ]]; then
    echo "KNOWN-BUG: $* [$KNOWN]"
    known=$((known + 1))
  else
    echo "FAIL: $*"
    failed=$((failed + 1))
  fi
}
check() { # check DESC CMD...: ok if CMD succeeds
  local desc=$1; shift
  if "$@"; then ok "$desc"; else fail "$desc"; fi
}

# run CMD...: run under timeout 30; sets RC, stdout in $T/out, stderr in $T/err.
run() {
  timeout 30 "$@" >"$T/out" 2>"$T/err"
  RC=$?
}

# Describe how the last run went wrong as a process (hang / crash), or return 1.
process_problem() {
  if ((RC == 124)); then
    echo "hang (killed by timeout 30)"
  elif ((RC >= 125 && RC <= 127)); then
    echo "could not run (exit $RC)"
  elif ((RC >= 128)); then
    echo "crash (exit $RC, signal $((RC - 128)))"
  elif grep -qE 'Segmentation|Aborted|terminate called|core dumped' "$T/err"; then
    echo "crash (stderr: $(head -c 200 "$T/err" | tr '\n' ' '))"
  else
    return 1
  fi
}

first_err() { head -n 3 "$T/err" | tr '\n' '|' | head -c 300; }

# expect_ok DESC CMD...: must exit 0 (stdout/stderr kept in $T/out, $T/err).
expect_ok() {
  local desc=$1; shift
  run "$@"
  local why
  if why=$(process_problem); then
    fail "$desc: $why"
  elif ((RC != 0)); then
    fail "$desc: exit $RC: $(first_err)"
  else
    ok "$desc"
  fi
}

# expect_fail DESC WORD CMD...: must exit exactly 1 without crashing or hanging,
# and print exactly one stderr line that contains WORD (case-insensitive).
expect_fail() {
  local desc=$1 word=$2; shift 2
  run "$@"
  local why lines
  lines=$(grep -c '' "$T/err")
  if why=$(process_problem); then
    fail "$desc: $why"
  elif ((RC != 1)); then
    fail "$desc: exit $RC, want 1: $(first_err)"
  elif ((lines != 1)); then
    fail "$desc: expected one stderr line, got $lines: $(first_err)"
  elif ! grep -qiF -- "$word" "$T/err"; then
    fail "$desc: stderr lacks '$word': $(first_err)"
  else
    ok "$desc ($(cat "$T/err"))"
  fi
}
