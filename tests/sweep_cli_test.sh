#!/usr/bin/env bash
# End-to-end test of `mvkp eval sweep` (issue 18): a small sweep writes its
# CSV, summary and two SVG curves, finds the target in frontal frames, and
# refuses impossible bands and bad input with a one-line error.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples.
set -u
# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init sweep

S=(eval sweep "$SAMPLES/starry_night.jpg" --background "$SAMPLES/building.jpg" "$SAMPLES/fruits.jpg")
expect_ok "small sweep" "$MVKP" "${S[@]}" --per-target 2 --methods mvkp,orb --size-edges 150,300 --tilt-edges 0,30,50 \
  --table-sizes 150-300 --table-tilts 0-30,30-50 --label test -o "$T/sw"
for f in sweep.csv summary.md summary.json size.svg tilt.svg; do
  check "writes $f" test -s "$T/sw/$f"
done
check "SVG curves are SVG documents" grep -q "^<svg" "$T/sw/size.svg"
check "CSV: a row per frame and method (2 + 4 frames x 2 methods)" \
  test "$(grep -vc '^frame,' "$T/sw/sweep.csv")" -eq 12
check "summary: mvkp finds the frontal 150-300 px frames, per-band times" $PY - "$T/sw/summary.json" <<'PYEOF'
import json, sys
j = json.load(open(sys.argv[1]))
rows = {r["band"]: r for r in j["table"]}
size = [r for b, r in rows.items() if b.startswith("150-300 px")][0]
assert size["mvkp"]["n"] == 2 and size["mvkp"]["ok5"] >= 0.5, size
assert size["mvkp"]["median_ms"] > 0 and "mvkp_split_ms" in size, size
assert j["targets"][0]["name"] == "starry_night" and j["targets"][0]["model_bytes"] > 0
assert set(j["curves"]) == {"size", "tilt"} and len(j["curves"]["tilt"]["mvkp"]) == 2
PYEOF
check "summary names the run" grep -q "mvkp eval sweep: test" "$T/sw/summary.md"

expect_ok "--save-frames writes frames, homographies and a manifest" "$MVKP" "${S[@]}" --per-target 1 --methods orb \
  --size-edges 150,300 --tilt-edges 0,30 --table-sizes 150-300 --table-tilts 0-30 --save-frames -o "$T/sf"
check "manifest lists both frames with their H" $PY - "$T/sf/frames" <<'PYEOF'
import os, sys
d = sys.argv[1]
lines = [l.split() for l in open(os.path.join(d, "manifest.txt"))]
assert len(lines) == 2
for t, f, h in lines:
    assert os.path.exists(t) and os.path.exists(os.path.join(d, f))
    assert len(open(os.path.join(d, h)).read().split()) == 9
PYEOF

# Impossible bands and bad input: one line, exit 1, before any work.
expect_fail "a size bigger than the frame" "bigger than the 640x480 frame" "$MVKP" "${S[@]}" --size-edges 200,900 -o "$T/x"
expect_fail "a tilt of 90 degrees" "90" "$MVKP" "${S[@]}" --tilt-edges 0,60,90 -o "$T/x"
expect_fail "edges that do not increase" "increase" "$MVKP" "${S[@]}" --size-edges 300,200 -o "$T/x"
expect_fail "a malformed band" "LO-HI" "$MVKP" "${S[@]}" --tilt-size 400 -o "$T/x"
expect_fail "an unknown method" "unknown method" "$MVKP" "${S[@]}" --methods mvkp,surf -o "$T/x"
expect_fail "a background that is not an image" "not an image" "$MVKP" eval sweep "$SAMPLES/starry_night.jpg" \
  --background "$0" -o "$T/x"
check "nothing written by the refused runs" test ! -e "$T/x"
cli_finish
