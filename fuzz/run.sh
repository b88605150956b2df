#!/usr/bin/env bash
# make fuzz: runs each libFuzzer target of BUILD (default build-san) for
# SECONDS (default 300) on its corpus, one after the other, and prints the
# executions each did. New inputs accumulate in BUILD/fuzz/corpus/<target>
# (the repository's seeds in fuzz/corpus/<target> are only read); crashes,
# leaks and timeouts are written to BUILD/fuzz/artifacts/ and make it fail.
# Usage: fuzz/run.sh [BUILD] [SECONDS] [TARGET...]
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-san}
seconds=${2:-300}
shift 2 2>/dev/null || shift $#
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then  # every target built (mvkp_fuzz_<name>), the seed writer excepted
  for bin in "$build"/fuzz/mvkp_fuzz_*; do
    t=${bin##*/mvkp_fuzz_}
    [ "$t" = seeds ] || [ ! -x "$bin" ] || targets+=("$t")
  done
fi
logs=$build/fuzz/logs
mkdir -p "$logs" "$build/fuzz/artifacts"
total=0
failed=()
printf '%-12s %12s %8s %7s  %s\n' target executions exec/s corpus result
for t in "${targets[@]}"; do
  bin=$build/fuzz/mvkp_fuzz_$t
  if [ ! -x "$bin" ]; then
    echo "fuzz: $bin is missing (make sanitize builds it)" >&2
    exit 2
  fi
  mkdir -p "$build/fuzz/corpus/$t"
  "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$build/fuzz/artifacts/$t-" "$build/fuzz/corpus/$t" "fuzz/corpus/$t" >"$logs/$t.log" 2>&1
  rc=$?
  runs=$(sed -n 's/^stat::number_of_executed_units: *\([0-9]*\).*/\1/p' "$logs/$t.log" | tail -1)
  runs=${runs:-0}
  total=$((total + runs))
  corpus=$(find "$build/fuzz/corpus/$t" -type f | wc -l)
  result=ok
  if [ $rc -ne 0 ]; then
    result="FAILED (exit $rc, see $logs/$t.log)"
    failed+=("$t")
  fi
  printf '%-12s %12s %8s %7s  %s\n' "$t" "$runs" "$((runs / (seconds > 0 ? seconds : 1)))" "$corpus" "$result"
done
echo "total: $total executions"
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: failures in ${failed[*]}; inputs in $build/fuzz/artifacts/" >&2
  exit 1
fi
