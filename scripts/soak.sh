#!/usr/bin/env bash
# `make soak` (issue 19, item 5): 32 loopback clients (recognition, exhibit
# reads, admin edits, slow sockets) against `mvkp serve` for SECONDS (600),
# then recognition p99 alone vs with 8 slow sockets open. Sets up its own
# database, frames and server under OUT; report in OUT/report.json and
# OUT/summary.txt; exit status 1 when a goal fails (see scripts/soak.py).
#   scripts/soak.sh [MVKP] [OUT] [SECONDS] [soak.py options...]
set -euo pipefail
mvkp=${1:-build/mvkp}
out=${2:-out/soak}
secs=${3:-600}
shift $(( $# < 3 ? $# : 3 ))
here=$(cd "$(dirname "$0")" && pwd)
exec /usr/bin/python3 "$here/soak.py" --mvkp "$mvkp" --out "$out" --seconds "$secs" "$@"
