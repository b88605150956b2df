#!/usr/bin/env bash
# Reproduces the thesis's RIFS experiments on synthetic views of real targets:
#   Fig. 3.16: average corner error per target, alpha = 0 vs alpha = 0.5,
#              both keeping the same top 30 % of the view tracks;
#   Fig. 3.18: average error (and success rate) as alpha sweeps 0 -> 1.
# Thesis settings (§3.4.5): 50 general views + 72 rotation views, 10 k-means
# centres, 20 kernels. Each target gets VIEWS test views from `mvkp synth`
# (perspective, clutter, lighting, blur, noise) that the selection never sees;
# every setting is trained with SEEDS training seeds and the results pooled.
#
#   scripts/rifs-experiments.sh OUT_DIR [--quick]
# Writes OUT_DIR/runs/*.json (mvkp eval output), OUT_DIR/rifs-report.md and
# the plots OUT_DIR/fig3_16.svg, OUT_DIR/fig3_18.svg (scripts/plot_rifs.py).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
mvkp=${MVKP:-$here/build/mvkp}
out=${1:?usage: rifs-experiments.sh OUT_DIR [--quick]}
quick=${2:-}
views=100; seeds="1 2 3"; alphas="0 0.1 0.2 0.3 0.4 0.5 0.6 0.7 0.8 0.9 1"
if [ "$quick" = --quick ]; then views=20; seeds="1"; alphas="0 0.5 1"; fi
mkdir -p "$out/runs"

# Targets: the bundled samples and the held-out OpenCV / scikit-image images.
"$here/scripts/fetch-eval-images.sh" "$out/images" >/dev/null
targets=("$here"/samples/*.jpg "$out"/images/{chelsea.png,rocket.jpg,camera.png,motorcycle_left.png,messi5.jpg,butterfly.jpg,aero1.jpg,home.jpg,board.jpg,hubble_deep_field.jpg,page.png})
if [ ! -f "$out/sets/.done-$views" ]; then
  rm -rf "$out/sets"
  MVKP=$mvkp "$here/scripts/make-synth-sets.sh" "$out/sets" "$views" "${targets[@]}" >/dev/null
  touch "$out/sets/.done-$views"
fi
common=(--select rifs --rifs-stats "${RIFS_STATS:-all}" --views 50 --rotation-views 72 --clusters 10 --kernels 20)
run() {  # run NAME ARGS...
  local name=$1; shift
  [ -f "$out/runs/$name.json" ] && return 0
  "$mvkp" eval "$out"/sets/*/manifest.txt "${common[@]}" "$@" --json "$out/runs/$name.json.tmp" >/dev/null 2>&1
  mv "$out/runs/$name.json.tmp" "$out/runs/$name.json"
}
for s in $seeds; do
  for a in $alphas; do
    echo "keep 30%, alpha $a, seed $s" >&2
    run "keep30p-alpha$a-seed$s" --keep 30% --alpha "$a" --seed "$s"
  done
  for a in 0 0.5; do
    echo "keep 50, alpha $a, seed $s" >&2
    run "keep50-alpha$a-seed$s" --keep 50 --alpha "$a" --seed "$s"
  done
done
/usr/bin/python3 "$here/scripts/plot_rifs.py" "$out"
