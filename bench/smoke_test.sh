#!/usr/bin/env bash
# bench_knn_smoke: mvkp_bench_knn on small random data (N=2000, DIM=20, 50
# queries) exits 0 and prints a result line for every method CMake compiled in
# (METHODS); exact methods reach recall 1; --dump/--db round trip; bad input.
set -euo pipefail
: "${BENCH:?path to mvkp_bench_knn}" "${METHODS:?expected method names}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

listed=$("$BENCH" --list-methods | tr '\n' ' ' | sed 's/ $//')
[ "$listed" = "$METHODS" ] || fail "--list-methods says '$listed', CMake expected '$METHODS'"

out=$("$BENCH" --random 2000 20 --nq 50 --k 2 --batch-seconds 0 --dump "$tmp/db.fvecs" "$tmp/q.fvecs")
echo "$out"
for m in $METHODS; do
  line=$(grep -E "^$m +[0-9]" <<<"$out") || fail "no result line for $m"
  # columns: method build single batch recall heap struct
  recall=$(awk '{print $5}' <<<"$line")
  case "$m" in
    mvkp-brute-2nn|mvkp-brute-knn|faiss-flat)
      [ "$recall" = "1.0000" ] || fail "$m is exact but reports recall $recall" ;;
  esac
done

[ "$(stat -c %s "$tmp/db.fvecs")" -eq $((2000 * (4 + 4 * 20))) ] || fail "--dump wrote a wrong-sized database"
out2=$("$BENCH" --db "$tmp/db.fvecs" --queries "$tmp/q.fvecs" --methods mvkp-brute-knn --json)
grep -q '"name": "mvkp-brute-knn"' <<<"$out2" || fail "--db/--queries --json run has no mvkp-brute-knn entry"
grep -q '"recall_at_1_single": 1.0' <<<"$out2" || fail "--db/--queries run: recall is not 1"
if command -v python3 > /dev/null; then python3 -m json.tool <<<"$out2" > /dev/null || fail "--json output is not JSON"; fi

set +e
err=$("$BENCH" --db "$tmp/missing.fvecs" --queries "$tmp/q.fvecs" 2>&1)
code=$?
set -e
[ $code -eq 1 ] || fail "missing database: exit code $code, expected 1"
grep -q "missing.fvecs: no such file" <<<"$err" || fail "missing database: message '$err'"
echo "bench_knn_smoke: ok ($METHODS)"
