#!/usr/bin/env bash
# The kNN benchmark suite (issue 3): mvkp_bench_knn on descriptors of real
# images, databases of 4 000, 50 000 and 1 000 000 vectors x {20-D WH, 64-D
# SIFT-PCA, 128-D SIFT}, k = 2, single thread, single queries and batched.
#
#   bench/run_knn_suite.sh OUTDIR [--quick] [--generate-only]
#
# --quick: only 4 000 and 50 000. --generate-only: write the datasets, run nothing.
# Environment: BENCH (default build/mvkp_bench_knn, then build-bench/), PYTHON (default /usr/bin/python3), METHODS (a
# comma-separated subset, default all compiled in).
#
# OUTDIR/images/   source images: scripts/fetch-eval-images.sh (opencv-doc and
#                  python3-skimage .debs via apt-get download) + samples/*.jpg;
#                  images.txt lists them in the order used, with SHA-256
# OUTDIR/data/     DESC-N.fvecs / DESC-N-q.fvecs (1000 queries each) and
#                  DESC-N.txt (how they were made): generated once, then reused
# OUTDIR/runs/     DESC-N.json (mvkp_bench_knn --json), .log (stderr), .time
# OUTDIR/knn_suite.json, knn_suite.txt (combined table), knn_suite.svg (plot)
set -euo pipefail

usage() { echo "usage: $0 OUTDIR [--quick] [--generate-only]" >&2; exit 2; }
[ $# -ge 1 ] || usage
out=$1; shift
quick=0; gen_only=0
for a in "$@"; do
  case "$a" in
    --quick) quick=1 ;;
    --generate-only) gen_only=1 ;;
    *) usage ;;
  esac
done

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
if [ -z "${BENCH:-}" ]; then
  for b in "$root/build/mvkp_bench_knn" "$root/build-bench/mvkp_bench_knn"; do
    [ -x "$b" ] && { BENCH=$b; break; }
  done
fi
[ -x "${BENCH:-}" ] || { echo "mvkp_bench_knn not found: build it or set BENCH" >&2; exit 1; }
PYTHON=${PYTHON:-/usr/bin/python3}
METHODS=${METHODS:-}

sizes=(4000 50000 1000000)
[ $quick -eq 1 ] && sizes=(4000 50000)
descs=(wh sift64 sift128)
gen_nq=1000            # queries generated per dataset
k=2

mkdir -p "$out"/images "$out"/data "$out"/runs
out=$(cd "$out" && pwd)
now() { date +%s%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", (b - a) / 1e9 }'; }  # START_NS END_NS
t_start=$(now)

# --- images ---------------------------------------------------------------
if [ ! -f "$out/images/images.txt" ]; then
  bash "$root/scripts/fetch-eval-images.sh" "$out/images/eval" > /dev/null
  cp "$root"/samples/*.jpg "$out/images/"
  # Fixed order: the evaluation images, then the samples, each sorted by name.
  (cd "$out/images" && { printf '%s\n' eval/* | LC_ALL=C sort; printf '%s\n' ./*.jpg | sed 's|^\./||' | LC_ALL=C sort; }) |
    while read -r f; do sha256sum "$out/images/$f" | awk -v f="$f" '{print f, $1}'; done > "$out/images/images.txt.tmp"
  mv "$out/images/images.txt.tmp" "$out/images/images.txt"
fi
images=()
while read -r f _; do images+=("$out/images/$f"); done < "$out/images/images.txt"
echo "images: ${#images[@]} (list in $out/images/images.txt)"

gen_args() {  # DESC -> mvkp_bench_knn generation options (images appended by the caller)
  case "$1" in
    wh) echo "--generate-wh" ;;
    sift64) echo "--dim 64 --generate-sift" ;;
    sift128) echo "--dim 128 --generate-sift" ;;
  esac
}

# --- datasets (cached) -----------------------------------------------------
for n in "${sizes[@]}"; do
  for d in "${descs[@]}"; do
    base="$out/data/$d-$n"
    [ -f "$base.fvecs" ] && [ -f "$base-q.fvecs" ] && [ -f "$base.txt" ] && continue
    echo "generating $d n=$n ..."
    t0=$(now)
    # shellcheck disable=SC2046
    "$BENCH" --n "$n" --nq "$gen_nq" --seed 1 --dump "$base.tmp.fvecs" "$base-q.tmp.fvecs" --dump-only \
      $(gen_args "$d") "${images[@]}" > "$base.txt.tmp" 2> "$base.gen.log"
    echo "generation wall $(secs "$t0" "$(now)") s" >> "$base.txt.tmp"
    mv "$base.tmp.fvecs" "$base.fvecs"
    mv "$base-q.tmp.fvecs" "$base-q.fvecs"
    mv "$base.txt.tmp" "$base.txt"
    sed -n 1p "$base.txt"
  done
done
t_gen=$(now)
[ $gen_only -eq 1 ] && { echo "datasets in $out/data"; exit 0; }

# --- runs -------------------------------------------------------------------
for n in "${sizes[@]}"; do
  for d in "${descs[@]}"; do
    base="$out/data/$d-$n"
    run="$out/runs/$d-$n"
    nq=1000; repeat=1
    [ "$n" -ge 1000000 ] && nq=200   # keeps FAISS flat (scalar, reference BLAS) bounded
    [ "$n" -le 4000 ] && repeat=3    # short timings: lowest median of 3 passes
    args=(--db "$base.fvecs" --queries "$base-q.fvecs" --nq "$nq" --k "$k" --repeat "$repeat" --json)
    [ -n "$METHODS" ] && args+=(--methods "$METHODS")
    echo "running $d n=$n nq=$nq repeat=$repeat ..."
    t0=$(now)
    # Exit code 1 with a JSON object: some method failed (its entry says why),
    # the others are reported; anything else is fatal.
    code=0
    "$BENCH" "${args[@]}" > "$run.json.tmp" 2> "$run.log" || code=$?
    secs "$t0" "$(now)" > "$run.time"
    if [ $code -ne 0 ]; then
      if [ $code -eq 1 ] && "$PYTHON" -c 'import json, sys; json.load(open(sys.argv[1]))' "$run.json.tmp" 2> /dev/null; then
        echo "  WARNING: $(grep -c FAILED "$run.log") method(s) failed, see $run.log" >&2
      else
        echo "mvkp_bench_knn failed ($code), see $run.log:" >&2
        tail -5 "$run.log" >&2
        exit 1
      fi
    fi
    mv "$run.json.tmp" "$run.json"
    echo "  $(cat "$run.time") s"
  done
done
t_end=$(now)

# --- merge, table, plot -------------------------------------------------------
cmd="bench/run_knn_suite.sh OUTDIR"
[ $quick -eq 1 ] && cmd+=" --quick"
suite_args=("$out" --command "$cmd" --sizes "${sizes[*]}" --descriptors "${descs[*]}"
            --generation-seconds "$(secs "$t_start" "$t_gen")" --run-seconds "$(secs "$t_gen" "$t_end")")
"$PYTHON" "$here/knn_suite.py" "${suite_args[@]}" | tee "$out/knn_suite.txt"
"$PYTHON" "$here/plot_knn.py" "$out/knn_suite.json" "$out/knn_suite.svg"
echo "wrote $out/knn_suite.json, $out/knn_suite.txt, $out/knn_suite.svg"
