#!/usr/bin/env bash
# End-to-end tests of `mvkp recognize`: a database of sample targets, a
# synthetic view of one is recognised with that id and a real inlier count,
# a non-target image finds nothing, two queries with --draw, bad input
# (missing / corrupt / empty database, unreadable query) fails cleanly.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples.
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init recognize

DB=$T/museum.db
expect_ok "db create" "$MVKP" db create "$DB"
expect_ok "db add starry" "$MVKP" db add "$DB" --id starry --image "$SAMPLES/starry_night.jpg" --title "The Starry Night"
expect_ok "db add coffee" "$MVKP" db add "$DB" --id coffee --image "$SAMPLES/coffee.jpg" --title "Coffee"
expect_ok "db add building" "$MVKP" db add "$DB" --id building --image "$SAMPLES/building.jpg"

# The database holds starry_night.jpg at full size (400 px wide); the views
# keep that size (--target-size 0) so the ground truth is in its pixels.
expect_ok "synth 2 views of starry_night" "$MVKP" synth "$SAMPLES/starry_night.jpg" --n 2 --seed 5 --target-size 0 -o "$T/s"

expect_ok "recognize a view of starry (JSON)" "$MVKP" recognize "$DB" "$T/s/view_0000.png" --json
check "JSON: starry found first, >= 12 inliers, outline near the ground truth, fields present" $PY -c "
import json, sys
j = json.loads(open('$T/out').read().strip().splitlines()[0])
f = j['found']
ok = len(f) >= 1 and f[0]['id'] == 'starry' and f[0]['title'] == 'The Starry Night' and f[0]['inliers'] >= 12
ok = ok and all(x['id'] == 'starry' for x in f)
ok = ok and len(f[0]['homography']) == 3 and len(f[0]['outline']) == 4 and f[0]['votes'] >= f[0]['inliers']
ok = ok and 0 < f[0]['score'] <= 1 and j['keypoints'] > 0 and j['targets'] == 3
ok = ok and all(k in j['time_ms'] for k in ('detect', 'describe', 'search', 'verify', 'total'))
# ground truth: H_0000.txt maps target pixels to view pixels
H = [[float(v) for v in l.split()] for l in open('$T/s/H_0000.txt') if l.strip() and not l.startswith('#')]
import struct
def size(p):
    with open(p, 'rb') as fh:
        d = fh.read(24)
    return struct.unpack('>II', d[16:24])
W, Hh = size('$T/s/target.png')
def proj(M, x, y):
    d = M[2][0] * x + M[2][1] * y + M[2][2]
    return ((M[0][0] * x + M[0][1] * y + M[0][2]) / d, (M[1][0] * x + M[1][1] * y + M[1][2]) / d)
corners = [(0, 0), (W - 1, 0), (W - 1, Hh - 1), (0, Hh - 1)]
err = sum(((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5 for a, b in zip((proj(H, *c) for c in corners), f[0]['outline'])) / 4
print('corner error %.2f px, %d inliers' % (err, f[0]['inliers']))
sys.exit(0 if ok and err < 5 else 1)"

expect_ok "recognize a non-target image" "$MVKP" recognize "$DB" "$SAMPLES/fruits.jpg" --json
check "non-target: found is empty" $PY -c "
import json, sys
j = json.loads(open('$T/out').read())
sys.exit(0 if j['found'] == [] else 1)"

expect_ok "recognize two queries, text mode, --draw" "$MVKP" recognize "$DB" "$T/s/view_0001.png" "$SAMPLES/baboon.jpg" \
  --draw "$T/draw.png"
check "text: a load line, then one line per query (starry; no target)" \
  bash -c "grep -q '^loaded 3 targets' '$T/out' && grep -q 'view_0001.png: starry' '$T/out' && grep -q 'baboon.jpg: no target' '$T/out' && test \$(grep -c '' '$T/out') -eq 3"
check "--draw wrote draw-0.png and draw-1.png" test -s "$T/draw-0.png" -a -s "$T/draw-1.png"

# The word-based search (inverted file, built-in vocabulary) finds the same target.
expect_ok "recognize --search words (JSON)" "$MVKP" recognize "$DB" "$T/s/view_0000.png" --json --search words
check "words: starry found first with >= 12 inliers, nothing else" $PY -c "
import json
j = json.loads(open('$T/out').read().strip().splitlines()[0])
f = j['found']
import sys
sys.exit(0 if len(f) >= 1 and f[0]['id'] == 'starry' and f[0]['inliers'] >= 12 and all(x['id'] == 'starry' for x in f) else 1)"
expect_ok "recognize --search words, a non-target" "$MVKP" recognize "$DB" "$SAMPLES/baboon.jpg" --search words
check "words: baboon.jpg: no target" grep -q 'baboon.jpg: no target' "$T/out"
check "words: the targets came from the stored encodings" grep -q 'loaded 3 targets.*3 from stored word encodings' "$T/out"
# A database without them (older, or made with other settings) still works: the models are encoded at load.
$PY -c "import sqlite3; c = sqlite3.connect('$DB'); c.execute('DELETE FROM encodings'); c.commit()"
expect_ok "recognize --search words without stored encodings" "$MVKP" recognize "$DB" "$T/s/view_0000.png" --search words
check "words without encodings: 0 from encodings, starry found" \
  bash -c "grep -q '0 from stored word encodings' '$T/out' && grep -q 'view_0000.png: starry' '$T/out'"
check "unknown --search is refused (usage error)" bash -c "! '$MVKP' recognize '$DB' '$SAMPLES/fruits.jpg' --search bogus 2>/dev/null"

# The vocabulary command: train a small one, read it back, refuse a corrupt one.
expect_ok "vocab train (64 words, 2 images)" "$MVKP" vocab train "$SAMPLES/fruits.jpg" "$SAMPLES/building.jpg" \
  -o "$T/v.vocab" --words 64 --views 20
expect_ok "vocab info" "$MVKP" vocab info "$T/v.vocab"
check "vocab info: 64 words, 20-D" grep -q '64 words, 20-D' "$T/out"
head -c 100 "$T/v.vocab" >"$T/cut.vocab"
expect_fail "truncated vocabulary" "$T/cut.vocab" "$MVKP" vocab info "$T/cut.vocab"
check "vocab train without -o is refused (usage error)" bash -c "! '$MVKP' vocab train '$SAMPLES/fruits.jpg' 2>/dev/null"
expect_fail "more words than samples" "samples" "$MVKP" vocab train "$SAMPLES/fruits.jpg" -o "$T/w.vocab" --words 1000000

# Bad input.
expect_fail "missing database" "$T/none.db" "$MVKP" recognize "$T/none.db" "$SAMPLES/fruits.jpg"
printf 'hello' >"$T/text.db"
expect_fail "not a database" "not an mvkp target database" "$MVKP" recognize "$T/text.db" "$SAMPLES/fruits.jpg"
expect_ok "db create (empty)" "$MVKP" db create "$T/empty.db"
expect_fail "empty database" "DB has no targets" "$MVKP" recognize "$T/empty.db" "$SAMPLES/fruits.jpg"
printf 'not an image' >"$T/bad.png"
expect_fail "unreadable query" "$T/bad.png" "$MVKP" recognize "$DB" "$T/bad.png" --json
check "unreadable query: JSON error line" $PY -c "
import json, sys
j = json.loads(open('$T/out').read())
sys.exit(0 if j['query'] == '$T/bad.png' and j['error'] else 1)"
run "$MVKP" recognize "$DB" "$T/bad.png" "$T/s/view_0000.png" --json
check "unreadable query among good ones: exit 1, the good one still recognised" $PY -c "
import json, sys
l = [json.loads(x) for x in open('$T/out').read().strip().splitlines()]
sys.exit(0 if $RC == 1 and len(l) == 2 and 'error' in l[0] and l[1]['found'][0]['id'] == 'starry' else 1)"

# One damaged row (issue 19): the others are still recognised, with a warning.
cp "$DB" "$T/damaged.db"
$PY -c "import sqlite3; c = sqlite3.connect('$T/damaged.db'); c.execute(\"UPDATE targets SET model = x'00' WHERE id = 'coffee'\"); c.commit()"
expect_ok "recognize with one damaged row" "$MVKP" recognize "$T/damaged.db" "$T/s/view_0000.png" --json
check "damaged row: skipped with a warning naming it, starry still found" $PY -c "
import json, sys
j = json.loads(open('$T/out').read().strip().splitlines()[0])
err = open('$T/err').read()
sys.exit(0 if j['found'][0]['id'] == 'starry' and j['targets'] == 2 and 'coffee' in err and 'skipped' in err else 1)"

cli_finish
