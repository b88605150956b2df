#!/usr/bin/env bash
# End-to-end tests of `mvkp pair --method ...` (every method prints the same
# correspondence JSON and finds a known homography) and `mvkp eval oxford`
# (report files, counts, and clean failures on bad folders).
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples. Needs no
# network; Python side: standard library only.
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init oxford

# --- a small Oxford-style sequence with known homographies (from mvkp synth) ----
"$MVKP" synth "$SAMPLES/building.jpg" --n 3 --seed 5 --no-clutter --perspective 0.05 --min-scale 0.8 --max-scale 1.3 \
  --target-size 400 -o "$T/synth" >/dev/null || fail "synth"
mkdir -p "$T/seq"
cp "$T/synth/target.png" "$T/seq/img1.png"
for i in 0 1 2; do
  cp "$T/synth/view_000$i.png" "$T/seq/img$((i + 2)).png"
  cp "$T/synth/H_000$i.txt" "$T/seq/H1to$((i + 2))p"
done

# corner_ok H_FILE TOL: the JSON in $T/out has every key, and its homography is
# within TOL px (mean over img1's corners) of H_FILE.
corner_ok() {
  $PY - "$T/out" "$1" "$2" "$T/seq/img1.png" <<'PYEOF'
import json, struct, sys
j = json.loads(open(sys.argv[1]).read())
need = {"method", "keypoints1", "keypoints2", "time_ms", "homography", "matches"}
if not need <= set(j) or "query" not in j["time_ms"] or "total" not in j["time_ms"]:
    sys.exit("missing keys")
if j["homography"] is None:
    sys.exit("not found")
H = [[float(v) for v in l.split()] for l in open(sys.argv[2]) if l.strip()]
E = j["homography"]
w, h = struct.unpack(">II", open(sys.argv[4], "rb").read(24)[16:24])
def ap(M, x, y):
    d = M[2][0] * x + M[2][1] * y + M[2][2]
    return ((M[0][0] * x + M[0][1] * y + M[0][2]) / d, (M[1][0] * x + M[1][1] * y + M[1][2]) / d)
err = 0
for x, y in ((0, 0), (w, 0), (w, h), (0, h)):
    a, b = ap(E, x, y), ap(H, x, y)
    err += ((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5 / 4
m = j["matches"]
if not m or any(len(r) != 6 or r[5] not in (0, 1) for r in m):
    sys.exit("bad matches")
sys.exit(0 if err < float(sys.argv[3]) else "corner error %.2f" % err)
PYEOF
}

for m in mvkp cdikp sift orb akaze aug-sift aug-cdikp; do
  expect_ok "pair --method $m --json" "$MVKP" pair "$T/seq/img1.png" "$T/seq/img2.png" --method "$m" --json
  tol=5
  [[ $m == aug-cdikp ]] && tol=10
  if why=$(corner_ok "$T/seq/H1to2p" $tol 2>&1); then ok "pair --method $m: correspondence JSON, homography within $tol px"; else fail "pair --method $m: $why"; fi
done
expect_ok "pair --method cdikp --draw" "$MVKP" pair "$T/seq/img1.png" "$T/seq/img2.png" --method cdikp --draw "$T/d.png"
check "--draw wrote a PNG" test -s "$T/d.png"
run "$MVKP" pair "$T/seq/img1.png" "$T/seq/img2.png" --method surf
if ((RC != 0)) && ! process_problem >/dev/null && grep -q "method" "$T/err"; then ok "pair --method surf rejected"; else fail "pair --method surf: exit $RC"; fi
$PY -c "open('$T/flat.pgm','wb').write(b'P5\n200 150\n255\n' + bytes([77]) * 30000)"
expect_fail "pair --method sift with a uniform query" "no keypoints" "$MVKP" pair "$T/seq/img1.png" "$T/flat.pgm" --method sift

# --- eval oxford -------------------------------------------------------------------
expect_ok "eval oxford on an Oxford-style folder" \
  "$MVKP" eval oxford "$T/seq" --methods cdikp,sift,aug-sift -o "$T/rep"
for f in summary.csv summary.json pairs.csv homography.csv matches.svg recall_seq.svg; do
  check "report has $f" test -s "$T/rep/$f"
done
check "pairs.csv: 3 methods x 3 pairs x 10 ratios" test "$(($(grep -c '' "$T/rep/pairs.csv") - 1))" -eq 90
check "summary.json: every method found the target in every pair, with per-keypoint times" $PY -c "
import json, sys
s = json.load(open('$T/rep/summary.json'))['summary']
ok = all(s[m]['ok10'] == 1.0 and s[m]['pairs'] == 3 and s[m]['describe_us_per_keypoint'] > 0 for m in ('cdikp', 'sift'))
ok = ok and s['aug-sift']['augment_us_per_keypoint'] > 0 and s['cdikp']['descriptor_bytes'] == 80
sys.exit(0 if ok else 1)"
check "SVGs are complete documents" $PY -c "
import sys
for f in ('matches.svg', 'recall_seq.svg'):
    t = open('$T/rep/' + f).read()
    if not (t.startswith('<svg') and t.rstrip().endswith('</svg>')): sys.exit(1)"
expect_ok "eval oxford on a mvkp synth folder (manifest)" "$MVKP" eval oxford "$T/synth" --methods cdikp -o "$T/rep2"
check "manifest folder: 3 pairs" test "$(($(grep -c '' "$T/rep2/homography.csv") - 1))" -eq 3

# Bad folders: one line naming what is wrong, exit 1.
mkdir -p "$T/empty"
expect_fail "eval oxford: folder without img1" "$T/empty" "$MVKP" eval oxford "$T/empty" -o "$T/r"
expect_fail "eval oxford: missing folder" "$T/nope" "$MVKP" eval oxford "$T/nope" -o "$T/r"
mkdir -p "$T/noh"; cp "$T/seq/img1.png" "$T/seq/img2.png" "$T/noh/"
expect_fail "eval oxford: image without its homography" "H1to2p" "$MVKP" eval oxford "$T/noh" -o "$T/r"
mkdir -p "$T/badh"; cp "$T/seq/img1.png" "$T/seq/img2.png" "$T/badh/"; echo "1 0 0 0 1" >"$T/badh/H1to2p"
expect_fail "eval oxford: malformed homography" "H1to2p" "$MVKP" eval oxford "$T/badh" -o "$T/r"
mkdir -p "$T/flat"; cp "$T/seq/img1.png" "$T/flat/"; cp "$T/flat.pgm" "$T/flat/img2.pgm"; cp "$T/seq/H1to2p" "$T/flat/"
expect_fail "eval oxford: an image without keypoints" "no keypoints" "$MVKP" eval oxford "$T/flat" --methods sift -o "$T/r"
mkdir -p "$T/nonem"; printf 'a.png b.png none\n' >"$T/nonem/manifest.txt"
expect_fail "eval oxford: manifest pair without homography" "none" "$MVKP" eval oxford "$T/nonem" -o "$T/r"
run "$MVKP" eval oxford "$T/seq" --methods bogus -o "$T/r"
if ((RC != 0)) && ! process_problem >/dev/null; then ok "eval oxford --methods bogus rejected"; else fail "--methods bogus: exit $RC"; fi
run "$MVKP" eval
if ((RC != 0)) && ! process_problem >/dev/null && grep -q "MANIFEST" "$T/err"; then ok "eval without manifest or subcommand"; else fail "bare eval: exit $RC"; fi

cli_finish
