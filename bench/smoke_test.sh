#!/usr/bin/env bash
# bench_knn_smoke: mvkp_bench_knn on small random data (N=2000, DIM=20, 50
# queries) exits 0 and prints a result line for every method CMake compiled in
# (METHODS); exact methods (brute force, FFVA, FAISS flat) reach recall 1;
# dist/q and mem/raw columns (exhaustive methods report n, FFVA at most n);
# --dump/--db round trip, --dump-only, --json fields; bad input.
set -euo pipefail
: "${BENCH:?path to mvkp_bench_knn}" "${METHODS:?expected method names}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

listed=$("$BENCH" --list-methods | tr '\n' ' ' | sed 's/ $//')
[ "$listed" = "$METHODS" ] || fail "--list-methods says '$listed', CMake expected '$METHODS'"

out=$("$BENCH" --random 2000 20 --nq 50 --k 2 --batch-seconds 0 --dump "$tmp/db.fvecs" "$tmp/q.fvecs")
echo "$out"
grep -qE "^method +build ms +us/q single +mean +us/q batch +recall@1 +B/vec heap +B/vec struct +mem/raw +dist/q$" <<<"$out" ||
  fail "table header lacks the expected columns"
grep -q "memory goal (issue 3): <= 1.1 x raw + 1 B/dim/vector = 108.0 B/vec at dim 20" <<<"$out" ||
  fail "no memory goal line"
for m in $METHODS; do
  line=$(grep -E "^$m +[0-9]" <<<"$out") || fail "no result line for $m"
  # columns: method build single mean batch recall heap struct mem/raw dist/q
  read -r _ _ _ _ _ recall _ _ memraw dist <<<"$line"
  [ -n "$dist" ] || fail "$m: no dist/q column"
  case "$m" in
    mvkp-brute-2nn|mvkp-brute-knn|mvkp-ffva-2nn|mvkp-ffva-knn|faiss-flat)
      [ "$recall" = "1.0000" ] || fail "$m is exact but reports recall $recall" ;;
  esac
  case "$m" in
    mvkp-brute-2nn|mvkp-brute-knn|faiss-flat)
      [ "$dist" = "2000" ] || fail "$m computes every distance, but dist/q is $dist" ;;
    mvkp-ffva-*|faiss-hnsw|hnswlib)
      awk -v d="$dist" 'BEGIN { exit !(d + 0 > 0 && d + 0 <= 2000) }' || fail "$m: dist/q $dist not in (0, 2000]" ;;
    flann-kdtree)
      [ "$dist" = "-" ] || fail "$m reports no distance count, but dist/q is $dist" ;;
  esac
  case "$m" in
    mvkp-*|faiss-*|hnswlib)
      awk -v r="$memraw" 'BEGIN { exit !(r + 0 >= 1) }' || fail "$m: mem/raw $memraw < 1 (the vectors alone are 1)" ;;
  esac
done

[ "$(stat -c %s "$tmp/db.fvecs")" -eq $((2000 * (4 + 4 * 20))) ] || fail "--dump wrote a wrong-sized database"
out2=$("$BENCH" --db "$tmp/db.fvecs" --queries "$tmp/q.fvecs" --methods mvkp-brute-knn --json)
grep -q '"name": "mvkp-brute-knn"' <<<"$out2" || fail "--db/--queries --json run has no mvkp-brute-knn entry"
grep -q '"recall_at_1_single": 1.0' <<<"$out2" || fail "--db/--queries run: recall is not 1"
grep -q '"distance_computations_per_query": 2000.0' <<<"$out2" || fail "--json: no distance_computations_per_query"
grep -q '"mem_over_raw": ' <<<"$out2" || fail "--json: no mem_over_raw"

out3=$("$BENCH" --random 300 8 --nq 5 --dump "$tmp/d2.fvecs" "$tmp/q2.fvecs" --dump-only)
grep -q "^data: random" <<<"$out3" || fail "--dump-only: no data line"
if grep -q "^method" <<<"$out3"; then fail "--dump-only ran the benchmark"; fi
[ "$(stat -c %s "$tmp/q2.fvecs")" -eq $((5 * (4 + 4 * 8))) ] || fail "--dump-only wrote a wrong-sized query file"
if command -v python3 > /dev/null; then python3 -m json.tool <<<"$out2" > /dev/null || fail "--json output is not JSON"; fi

set +e
err=$("$BENCH" --db "$tmp/missing.fvecs" --queries "$tmp/q.fvecs" 2>&1)
code=$?
set -e
[ $code -eq 1 ] || fail "missing database: exit code $code, expected 1"
grep -q "missing.fvecs: no such file" <<<"$err" || fail "missing database: message '$err'"
echo "bench_knn_smoke: ok ($METHODS)"
