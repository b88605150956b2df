#!/usr/bin/env bash
# Issue 7's latency goal: POST /api/recognize with 640x480 JPEG gallery frames
# against 100 exhibits, 2 server threads, loopback, end to end as the client
# sees it (median <= 25 ms, p99 <= 60 ms). One client, then two (one per
# server thread). `make serve-latency`.
#   scripts/serve-latency.sh [MVKP] [OUT]        (defaults: build/mvkp out/serve-latency)
# The frames and ground truth are the gallery set of scripts/gallery-eval.sh
# (made here with SIFT=0 when OUT/gallery/set is missing, ~2 min); the 100
# exhibits are its 28 targets plus 72 distractor pictures
# (scripts/serve_latency.py). Results: OUT/clients1.json, OUT/clients2.json.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
mvkp=${1:-build/mvkp}
out=${2:-out/serve-latency}
py=${PYTHON:-/usr/bin/python3}
[ -x "$mvkp" ] || { echo "serve-latency: no mvkp binary at $mvkp" >&2; exit 1; }
mkdir -p "$out"
# A copy, so a rebuild during the run cannot swap the binary under it.
cp "$mvkp" "$out/mvkp"
if [ ! -f "$out/gallery/set/ground_truth.json" ]; then
  SIFT=0 NOTARGET=${NOTARGET:-300} bash "$here/gallery-eval.sh" "$out/mvkp" "$out/gallery" >"$out/gallery.log" 2>&1 ||
    { tail -20 "$out/gallery.log" >&2; exit 1; }
fi
pool=("$out/gallery/debian")
[ -d out/quality-images ] && pool+=(out/quality-images)
for c in 1 2; do
  echo "serve-latency: $c client(s)"
  "$py" "$here/serve_latency.py" --mvkp "$out/mvkp" --set "$out/gallery/set" --pool "${pool[@]}" \
    --work "$out/work" --clients "$c" --json "$out/clients$c.json" 2> >(grep -v 'libpng warning\|Premature end' >&2)
done
