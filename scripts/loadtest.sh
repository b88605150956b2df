#!/usr/bin/env bash
# `make loadtest` (issue 7): a database of the sample targets, 40 synthetic
# 640x480-ish frames of them, then scripts/loadtest.py: 16 clients for 60 s
# with the concurrency bound above 16 (no 503 expected), and 10 s with the
# bound at 2 on purpose (503s expected). Results in OUT/*.json.
#   scripts/loadtest.sh [MVKP] [OUT] [SECONDS]
set -euo pipefail
mvkp=${1:-build/mvkp}
out=${2:-out/loadtest}
secs=${3:-60}
here=$(cd "$(dirname "$0")" && pwd)
samples="$here/../samples"
rm -rf "$out" && mkdir -p "$out/frames"
db="$out/museum.db"
"$mvkp" db create "$db" >/dev/null
for f in "$samples"/*.jpg; do
  id=$(basename "$f" .jpg)
  "$mvkp" db add "$db" --id "$id" --image "$f" --title "$id" >/dev/null
  "$mvkp" synth "$f" --n 7 --seed 11 -o "$out/s-$id" >/dev/null
  cp "$out/s-$id"/view_*.png "$out/frames/" 2>/dev/null || true
  for v in "$out/s-$id"/view_*.png; do mv "$out/frames/$(basename "$v")" "$out/frames/$id-$(basename "$v")"; done
done
echo "loadtest: $(ls "$out/frames" | wc -l) frames, $("$mvkp" db list "$db" | wc -l) lines of db list"
/usr/bin/python3 "$here/loadtest.py" --mvkp "$mvkp" --db "$db" --frames "$out/frames" --clients 16 \
  --seconds "$secs" --max-inflight 32 --json "$out/steady.json"
echo "loadtest: now with --max-inflight 2 on purpose (503s expected)"
/usr/bin/python3 "$here/loadtest.py" --mvkp "$mvkp" --db "$db" --frames "$out/frames" --clients 16 \
  --seconds 10 --warmup 2 --max-inflight 2 --json "$out/overload.json"
