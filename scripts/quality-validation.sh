#!/usr/bin/env bash
# Validates `mvkp quality` on a set of images (scripts/fetch-quality-images.sh):
#  - predictive power: Spearman correlation between the score and the
#    detection rate measured independently on `mvkp synth` views
#    (`mvkp eval`, success = corner error < 5 px);
#  - stability: score change under gain 0.5..1.5, gamma 0.7..1.4, brightness
#    +-40 and resizing 0.5x..2x;
#  - speed: wall time of `mvkp quality` per image (single thread).
#   scripts/quality-validation.sh OUT_DIR [IMAGES_DIR] [--quick]
# Writes OUT_DIR/quality-report.md and OUT_DIR/quality.json.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
mvkp=${MVKP:-$here/build/mvkp}
out=${1:?usage: quality-validation.sh OUT_DIR [IMAGES_DIR] [--quick]}
images=${2:-$out/images}
views=60; edits="gain0.5 gain0.7 gain1.5 gamma0.7 gamma1.4 bright-40 bright+40 resize0.5 resize2"
if [ "${3:-}" = --quick ]; then views=20; edits="gain0.5 resize0.5"; fi
mkdir -p "$out/synth" "$out/edits" "$out/score"
[ -f "$images/images.csv" ] || "$here/scripts/fetch-quality-images.sh" "$images" >/dev/null
i=0
for img in "$images"/*.png; do
  name=$(basename "${img%.*}")
  i=$((i + 1))
  echo "[$i] $name" >&2
  # Measured detection rate on independent synth views.
  if [ ! -f "$out/synth/$name.json" ]; then
    "$mvkp" synth "$img" --n "$views" --seed $((5000 + i)) -o "$out/synth/$name" >/dev/null
    if ! "$mvkp" eval "$out/synth/$name/manifest.txt" --json "$out/synth/$name.json" >/dev/null 2>"$out/synth/$name.err"; then
      echo '{"untrainable": true}' > "$out/synth/$name.json"   # too little texture to train: detection rate 0
    fi
  fi
  # Score of the original and of each edit, with wall time.
  for e in orig $edits; do
    f=$img
    if [ "$e" != orig ]; then
      f=$out/edits/$name-$e.png
      [ -f "$f" ] || /usr/bin/python3 "$here/scripts/quality_edit.py" "$img" "$e" "$f"
    fi
    j=$out/score/$name-$e.json
    if [ ! -f "$j" ]; then
      s=$(date +%s.%N)
      "$mvkp" quality "$f" --json > "$j.tmp" || true
      t=$(date +%s.%N)
      /usr/bin/python3 -c "import json,sys; d=json.load(open('$j.tmp')); d['wall_s']=$t-$s; json.dump(d,open('$j','w'))"
      rm -f "$j.tmp"
    fi
  done
done
/usr/bin/python3 "$here/scripts/quality_report.py" "$out" "$images"
