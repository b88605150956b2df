#!/usr/bin/env bash
# Builds synthetic evaluation sets (thesis §3.4.3 protocol plus perspective,
# clutter, lighting, blur, noise) for a list of targets:
#   make-synth-sets.sh OUT_DIR N_VIEWS TARGET...
# Each target gets OUT_DIR/<name>/ with target.png, views, H files and manifest.txt.
set -euo pipefail
mvkp=${MVKP:-build/mvkp}
out=$1; n=$2; shift 2
here=$(cd "$(dirname "$0")/.." && pwd)
i=0
for t in "$@"; do
  name=$(basename "${t%.*}")
  bg=""
  if [ $((i % 2)) -eq 1 ]; then bg="--background $here/samples/fruits.jpg"; fi
  "$mvkp" synth "$t" --n "$n" --seed $((100 + i)) $bg -o "$out/$name" >/dev/null
  i=$((i + 1))
done
ls "$out"/*/manifest.txt
