#!/usr/bin/env bash
# Does `mvkp quality` predict what users see (issue 18)? For every image of a
# set (default: scripts/fetch-quality-images.sh, 39 images from great to
# hopeless targets) it takes the score of `mvkp quality IMAGE --json` and the
# detection rate measured on the envelope benchmark's frames
# (`mvkp eval sweep IMAGE --methods mvkp`: pinhole-camera views band by band,
# 40-620 px and 0-80 degrees, on real photos the score never sees), then the
# Spearman correlation of the two. An image mvkp cannot train on counts as
# detected in 0 % of the frames.
#   scripts/quality-sweep.sh OUT_DIR IMAGES_DIR BACKGROUND... [-- SWEEP_ARGS...]
# Writes OUT_DIR/quality-sweep.md and OUT_DIR/quality-sweep.json.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
mvkp=${MVKP:-$here/build/mvkp}
out=${1:?usage: quality-sweep.sh OUT_DIR IMAGES_DIR BACKGROUND... [-- SWEEP_ARGS...]}
images=${2:?images folder}
shift 2
bgs=()
while [ $# -gt 0 ] && [ "$1" != -- ]; do bgs+=("$1"); shift; done
[ "${1:-}" = -- ] && shift
[ ${#bgs[@]} -gt 0 ] || { echo "quality-sweep: no background photos" >&2; exit 2; }
mkdir -p "$out/score" "$out/sweep"
shopt -s nullglob
imgs=("$images"/*.png "$images"/*.jpg)
[ ${#imgs[@]} -gt 0 ] || { echo "quality-sweep: no images in $images" >&2; exit 2; }
i=0
for img in "${imgs[@]}"; do
  name=$(basename "${img%.*}")
  i=$((i + 1))
  echo "[$i/${#imgs[@]}] $name" >&2
  [ -f "$out/score/$name.json" ] || "$mvkp" quality "$img" --json > "$out/score/$name.json" || true
  if [ ! -f "$out/sweep/$name/summary.json" ] && [ ! -f "$out/sweep/$name.untrainable" ]; then
    if ! "$mvkp" eval sweep "$img" --methods mvkp --background "${bgs[@]}" -o "$out/sweep/$name" \
         --frame-seed $((9000 + i)) "$@" > "$out/sweep/$name.log" 2>&1; then
      tail -1 "$out/sweep/$name.log" > "$out/sweep/$name.untrainable"
    fi
  fi
done
/usr/bin/python3 - "$out" "$here/scripts" <<'PY'
import glob, json, os, sys
out, scripts = sys.argv[1:]
sys.path.insert(0, scripts)
from quality_report import spearman
rows = []
for j in sorted(glob.glob(os.path.join(out, "score", "*.json"))):
    name = os.path.basename(j)[:-5]
    try:
        s = json.load(open(j))
    except ValueError:
        continue
    if "score" not in s:
        continue
    summ = os.path.join(out, "sweep", name, "summary.json")
    if os.path.exists(summ):
        d = json.load(open(summ))
        rate, n = d["all"]["mvkp"]["ok5"], d["all"]["mvkp"]["n"]
    elif os.path.exists(os.path.join(out, "sweep", name + ".untrainable")):
        rate, n = 0.0, 0
    else:
        continue
    rows.append({"image": name, "score": s["score"], "expected_rate": s.get("expected_detection_rate", 0.0),
                 "sweep_rate": rate, "sweep_frames": n})
if len(rows) < 3:
    sys.exit("quality-sweep: fewer than 3 images scored")
rho = spearman([r["score"] for r in rows], [r["sweep_rate"] for r in rows])
rho_e = spearman([r["expected_rate"] for r in rows], [r["sweep_rate"] for r in rows])
lines = ["# mvkp quality against the envelope sweep", "",
         f"- images: {len(rows)}",
         f"- Spearman(score, sweep detection rate) = {rho:.3f}   (goal >= 0.7)",
         f"- Spearman(expected rate, sweep detection rate) = {rho_e:.3f}", "",
         "| image | score | expected rate | sweep ok@5px | sweep frames |", "|---|---|---|---|---|"]
for r in sorted(rows, key=lambda r: -r["score"]):
    lines.append(f"| {r['image']} | {r['score']} | {r['expected_rate']:.2f} | {r['sweep_rate']:.2f} | {r['sweep_frames']} |")
open(os.path.join(out, "quality-sweep.md"), "w").write("\n".join(lines) + "\n")
json.dump({"spearman": rho, "spearman_expected": rho_e, "rows": rows}, open(os.path.join(out, "quality-sweep.json"), "w"), indent=1)
print("\n".join(lines))
PY
