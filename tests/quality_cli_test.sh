#!/usr/bin/env bash
# End-to-end tests of `mvkp quality` and of the RIFS training options
# (`mvkp train --select/--alpha/--keep/--min-stability/--explain`): real scores
# on real images, reasons for bad targets, clean failures on bad input.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples. Needs no
# network; Python side: standard library only. Output: one "ok: ..." /
# "FAIL: ..." line per check, then "N passed, M failed".
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init quality

# expect_reject DESC WORD CMD...: a bad option: non-zero exit, no crash, WORD on stderr.
expect_reject() {
  local desc=$1 word=$2; shift 2
  run "$@"
  local why
  if why=$(process_problem); then
    fail "$desc: $why"
  elif ((RC == 0)); then
    fail "$desc: accepted"
  elif ! grep -qiF -- "$word" "$T/err"; then
    fail "$desc: stderr lacks '$word': $(first_err)"
  else
    ok "$desc (exit $RC)"
  fi
}

# json_check DESC PYTHON_EXPR: evaluates EXPR with j = the JSON lines of $T/out (list).
json_check() {
  local desc=$1 expr=$2
  if $PY - "$T/out" "$expr" <<'PYEOF'; then ok "$desc"; else fail "$desc: $(head -c 300 "$T/out")"; fi
import json, sys
j = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
sys.exit(0 if eval(sys.argv[2]) else 1)
PYEOF
}

# pgm NAME W H VALUE: a uniform 8-bit PGM.
pgm() {
  $PY - "$1" "$2" "$3" "$4" <<'PYEOF'
import sys
name, w, h, v = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
open(name, "wb").write(b"P5\n%d %d\n255\n" % (w, h) + bytes([v]) * (w * h))
PYEOF
}

# --- mvkp quality: real outcomes ---------------------------------------------------
expect_ok "quality of a painting (--json --draw)" \
  "$MVKP" quality "$SAMPLES/starry_night.jpg" --json --draw "$T/q.png" --test-views 16
json_check "painting: score >= 70, detection rate >= 0.75, factors add up" \
  'len(j) == 1 and j[0]["score"] >= 70 and j[0]["expected_detection_rate"] >= 0.75 and abs(sum(f["points"] for f in j[0]["factors"].values()) - j[0]["score"]) <= 0.5 and len(j[0]["selected"]) == j[0]["selected_points"] > 0'
check "--draw wrote a PNG" test -s "$T/q.png"
check "--draw keeps the image size" $PY -c "
import struct, sys
d = open('$T/q.png', 'rb').read(24)
sys.exit(0 if d[:8] == b'\x89PNG\r\n\x1a\n' and struct.unpack('>II', d[16:24]) == (400, 319) else 1)"

pgm "$T/flat.pgm" 300 200 128
expect_ok "quality of a uniform image exits 0" "$MVKP" quality "$T/flat.pgm" --json
json_check "uniform image: score 0, reason 'uniform'" 'j[0]["score"] == 0 and j[0]["reasons"][0]["code"] == "uniform"'
pgm "$T/tiny.pgm" 16 16 10
expect_ok "quality of a 16x16 image exits 0" "$MVKP" quality "$T/tiny.pgm" --json
json_check "tiny image: score 0, reason 'too_small'" 'j[0]["score"] == 0 and j[0]["reasons"][0]["code"] == "too_small"'
expect_ok "quality, text output" "$MVKP" quality "$SAMPLES/coffee.jpg" --test-views 8
check "text output names score and factors" grep -q "quality .*/100" "$T/out"
check "text output: stable points with their training size" grep -qE "stable_points .*measured [0-9]+ at 400 px" "$T/out"

# --- mvkp quality: bad input ---------------------------------------------------------
printf 'not an image\n' >"$T/notimage.png"
expect_fail "quality of a non-image file" "$T/notimage.png" "$MVKP" quality "$T/notimage.png"
head -c 3000 "$SAMPLES/coffee.jpg" >"$T/trunc.jpg"
expect_fail "quality of a truncated JPEG" "$T/trunc.jpg" "$MVKP" quality "$T/trunc.jpg"
expect_fail "quality of a missing file" "$T/missing.png" "$MVKP" quality "$T/missing.png"
run "$MVKP" quality "$SAMPLES/coffee.jpg" "$T/missing.png" --json --test-views 4
if ((RC == 1)) && ! process_problem >/dev/null; then ok "good + missing image: exit 1"; else fail "good + missing image: exit $RC"; fi
json_check "good + missing image: a score for the good one, an error object for the other" \
  'len(j) == 2 and "score" in j[0] and "error" in j[1] and "missing.png" in j[1]["error"]'
expect_reject "quality --test-views 0" "test views" "$MVKP" quality "$SAMPLES/coffee.jpg" --test-views 0

# --- mvkp quality DB: the database as a whole (issue 20) ---------------------------
# The six samples plus a near-duplicate of coffee: a second photo of it (a
# camera view on a plain background, slightly scaled and tilted).
run "$MVKP" db create "$T/g.db"
for f in "$SAMPLES"/*.jpg; do
  id=$(basename "$f" .jpg)
  run "$MVKP" db add "$T/g.db" --id "$id" --image "$f"
  ((RC == 0)) || fail "db add $id: $(first_err)"
done
run "$MVKP" synth "$SAMPLES/coffee.jpg" -o "$T/dup" --n 1 --seed 3 --no-clutter --no-lighting --min-scale 0.9 \
  --max-scale 1.0 --perspective 0.05 --blur 0 --noise 0 --target-size 0 --width 700 --height 600
# Added on purpose: `db add` refuses a photo of an exhibit already there.
run "$MVKP" db add "$T/g.db" --id coffee_copy --image "$T/dup/view_0000.png" --allow-duplicate
((RC == 0)) || fail "db add coffee_copy: $(first_err)"
expect_ok "quality of a database (--json)" "$MVKP" quality "$T/g.db" --json --test-views 8
cp "$T/out" "$T/db.json"
json_check "database: 7 exhibits, each with a score" \
  'len(j) == 1 and len(j[0]["exhibits"]) == 7 and all(isinstance(e["quality"]["score"], int) for e in j[0]["exhibits"])'
json_check "database: coffee and its copy are look-alikes, both ways, and no other pair" \
  'sorted((p["a"], p["b"]) for p in j[0]["lookalikes"]) == [("coffee", "coffee_copy"), ("coffee_copy", "coffee")] and all(p["inliers"] >= 12 for p in j[0]["lookalikes"])'
expect_ok "quality of the six sample images" "$MVKP" quality "$SAMPLES"/*.jpg --json --test-views 8
check "database scores equal mvkp quality on the same images" $PY - "$T/db.json" "$T/out" <<'PYEOF'
import json, os, sys
db = json.loads(open(sys.argv[1]).read())
img = {os.path.basename(o["image"])[:-4]: o for o in map(json.loads, open(sys.argv[2]))}
ex = {e["id"]: e["quality"] for e in db["exhibits"]}
bad = [k for k, o in img.items() if (ex[k]["score"], ex[k]["stable_points"]) != (o["score"], o["stable_points"])]
print("differ:", bad) if bad else None
sys.exit(1 if bad or len(img) != 6 else 0)
PYEOF
expect_ok "quality of a database, text" "$MVKP" quality "$T/g.db" --test-views 4 --lookalike-views 0
check "text: the pair (stored image only)" \
  grep -qE "coffee -> coffee_copy: found in 1 of 1 probes" "$T/out"
check "text: time per exhibit" grep -qE "per exhibit: quality [0-9]+ ms, look-alike search [0-9]+ ms" "$T/out"
expect_fail "a file neither image nor database" "nor an mvkp target database" "$MVKP" quality "$T/notimage.png"
head -c 2000 "$T/g.db" >"$T/cut.db"
expect_fail "a truncated database" "cut.db: DB: database disk image is malformed" "$MVKP" quality "$T/cut.db"
expect_reject "--lookalike-views 99" "synthetic views" "$MVKP" quality "$T/g.db" --lookalike-views 99

# --- mvkp train: RIFS options ----------------------------------------------------------
expect_ok "train --explain --select rifs --keep 30%" \
  "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/c.mvkp" -q --explain --explain-rows 5 --select rifs --keep 30%
check "--explain prints the view-track summary" grep -q "^view tracks: .* eligible .* kept" "$T/out"
check "--explain prints the ranking rule" grep -q "ranking: rifs, alpha 0.50" "$T/out"
check "--explain prints 5 ranked rows" test "$(grep -cE '^ +[0-9]+ +[0-9.]+ +[0-9.]+ +[0-9]+ ' "$T/out")" -eq 5
check "--keep 30% keeps 30% of the eligible tracks" $PY -c "
import re, sys
m = re.search(r'(\d+) eligible .* (\d+) kept', open('$T/out').read())
e, k = int(m.group(1)), int(m.group(2))
sys.exit(0 if abs(k - 0.3 * e) <= 1 else 1)"
expect_ok "train --select stability --keep 50 --view-model affine" "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/s.mvkp" -q --explain --select stability --keep 50 --view-model affine
check "stability: 0 rotation views, 50 kept" grep -q "100 general + 0 rotation), 50 kept" "$T/out"
expect_ok "match with the RIFS model" "$MVKP" match "$T/c.mvkp" "$SAMPLES/coffee.jpg" --json
json_check "RIFS model finds its own target" 'j[0]["found"] and j[0]["inliers"] >= 20'
expect_reject "--keep abc" "--keep" "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/x.mvkp" --keep abc
expect_reject "--keep 0%" "--keep" "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/x.mvkp" --keep 0%
expect_reject "--keep 150%" "--keep" "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/x.mvkp" --keep 150%
expect_reject "--alpha 1.5" "--alpha" "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/x.mvkp" --alpha 1.5
expect_reject "--select best" "--select" "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/x.mvkp" --select best
expect_fail "--min-stability above the number of views" "min stability" \
  "$MVKP" train "$SAMPLES/coffee.jpg" -o "$T/x.mvkp" --min-stability 100000
check "no model left behind by rejected runs" test ! -e "$T/x.mvkp"

cli_finish
