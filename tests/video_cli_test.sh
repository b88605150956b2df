#!/usr/bin/env bash
# End-to-end tests of `mvkp video`: a generated clip of a database target
# moving smoothly over clutter is followed with temporal focus (found, with the
# right outline, in >= 95 % of the frames that show it; nothing reported once
# it is gone), the annotated video is written, and bad sources fail cleanly.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples; needs
# /usr/bin/python3 with numpy and cv2 (scripts/install-deps.sh) for the clip.
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init video
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

$PY "$HERE/scripts/make-test-video.py" "$SAMPLES/starry_night.jpg" "$SAMPLES/fruits.jpg" "$T/clip.avi" 40 --gone 8 ||
  fail "could not generate the clip"
DB=$T/v.db
"$MVKP" db create "$DB" >/dev/null
"$MVKP" db add "$DB" --id starry --image "$SAMPLES/starry_night.jpg" --title "The Starry Night" >/dev/null
"$MVKP" db add "$DB" --id coffee --image "$SAMPLES/coffee.jpg" >/dev/null

for mode in focus no-focus; do
  flag=()
  [[ $mode == no-focus ]] && flag=(--no-focus)
  expect_ok "video --json ($mode)" "$MVKP" video "$DB" "$T/clip.avi" --json -o "$T/out-$mode.mp4" "${flag[@]}"
  check "video ($mode): found with the right outline in >= 95% of visible frames, nothing once gone" $PY - "$T/out" "$T/clip.avi.H.txt" <<'PYEOF'
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
frames = [l for l in lines if "frame" in l]
hs = [l.split() for l in open(sys.argv[2])]
w, h = 300, 239  # starry_night.jpg (400x319) scaled to 300 px by make-test-video.py
def ap(H, x, y):
    d = H[6] * x + H[7] * y + H[8]
    return ((H[0] * x + H[1] * y + H[2]) / d, (H[3] * x + H[4] * y + H[5]) / d)
ok = visible = false_pos = 0
for f, hline in zip(frames, hs):
    if hline == ["none"]:
        false_pos += len(f["found"]) > 0
        continue
    visible += 1
    H = [float(v) for v in hline]
    # The recogniser's outline is in the database image's pixels (400x319): scale.
    sc = 400 / 300
    truth = [ap(H, x / sc, y / sc) for x, y in ((0, 0), (399, 0), (399, 318), (0, 318))]
    hit = [x for x in f["found"] if x["id"] == "starry"]
    if hit:
        err = sum(((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5 for a, b in zip(hit[0]["outline"], truth)) / 4
        ok += err < 5
summary = [l for l in lines if "summary" in l]
print(f"{ok}/{visible} visible frames within 5 px, {false_pos} false detections")
sys.exit(0 if summary and visible == 40 and ok >= 0.95 * visible and false_pos == 0 else 1)
PYEOF
  check "annotated video written ($mode)" test -s "$T/out-$mode.mp4"
done

# Bad sources.
expect_fail "video: missing file" "$T/none.avi" "$MVKP" video "$DB" "$T/none.avi"
: >"$T/empty.avi"
expect_fail "video: empty file" "$T/empty.avi" "$MVKP" video "$DB" "$T/empty.avi"
expect_fail "video: camera that cannot be opened" "camera 97" "$MVKP" video "$DB" 97
expect_fail "video: missing database" "$T/none.db" "$MVKP" video "$T/none.db" "$T/clip.avi"
"$MVKP" db create "$T/empty.db" >/dev/null
expect_fail "video: database without targets" "no targets" "$MVKP" video "$T/empty.db" "$T/clip.avi"

cli_finish
