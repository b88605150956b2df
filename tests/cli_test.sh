#!/usr/bin/env bash
# End-to-end tests of the mvkp command line: bad input must fail cleanly (non-zero
# exit, one stderr line naming the file, no crash, no hang), and the demo path
# (train -> synth -> match / pair) must give real, geometrically correct results.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples. Needs no network.
# Output: one "ok: ..." / "FAIL: ..." line per check ("KNOWN-BUG: ..." for product
# bugs that are reported but do not fail the suite), then "N passed, M failed".
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init cli

# known_bug NOTE CHECK...: run one check whose failure is a reported, unfixed product
# bug. Crashes and hangs still FAIL. When the bug is fixed the check prints "ok".
known_bug() {
  local KNOWN=$1
  shift
  "$@"
}

# expect_fail DESC NAME CMD...: must exit non-zero without crashing or hanging, and
# print exactly one stderr line that contains NAME (the offending file).
expect_fail() {
  local desc=$1 name=$2; shift 2
  run "$@"
  local why lines
  lines=$(grep -c '' "$T/err")
  if why=$(process_problem); then
    KNOWN='' fail "$desc: $why"
  elif ((RC == 0)); then
    fail "$desc: exit 0 on bad input"
  elif ((lines != 1)); then
    fail "$desc: expected one stderr line, got $lines: $(first_err)"
  elif ! grep -qF -- "$name" "$T/err"; then
    fail "$desc: stderr does not name '$name': $(first_err)"
  else
    ok "$desc (exit $RC: $(cat "$T/err"))"
  fi
}

# expect_reject DESC CMD...: bad options; non-zero exit, no crash, no hang, some message.
expect_reject() {
  local desc=$1; shift
  run "$@"
  local why
  if why=$(process_problem); then
    KNOWN='' fail "$desc: $why"
  elif ((RC == 0)); then
    fail "$desc: exit 0"
  elif [[ ! -s $T/err ]]; then
    fail "$desc: exit $RC but no message on stderr"
  else
    ok "$desc (exit $RC: $(first_err))"
  fi
}

# stderr_has DESC TEXT / stderr_lacks DESC TEXT: about the last run's stderr.
stderr_has() {
  if grep -qF -- "$2" "$T/err"; then ok "$1"; else fail "$1: stderr lacks '$2': $(first_err)"; fi
}
stderr_lacks() {
  if ! grep -qF -- "$2" "$T/err"; then ok "$1"; else fail "$1: stderr has '$2': $(first_err)"; fi
}

# --- fixtures ----------------------------------------------------------------

D=$T/in
mkdir -p "$D/a_directory.png"
: >"$D/empty.png"
echo "this is not an image" >"$D/text.png"
head -c "$(($(stat -c %s "$SAMPLES/coffee.jpg") / 2))" "$SAMPLES/coffee.jpg" >"$D/truncated.jpg"
printf 'P5 100000 100000 255\n\x01\x02\x03\x04' >"$D/huge.pgm"
printf 'P2 64 64 255\n1 2 3\n' >"$D/truncated_p2.pgm"

"$PY" - "$D" <<'EOF' || { echo "FAIL: cannot create test images with python3+cv2"; exit 1; }
import sys, cv2, numpy as np
d = sys.argv[1]
rng = np.random.default_rng(7)
noise = cv2.GaussianBlur(rng.integers(0, 256, (240, 320), dtype=np.uint8), (3, 3), 0)
cv2.imwrite(f"{d}/real.png", noise)                         # source for truncated.png
png = bytearray(open(f"{d}/real.png", "rb").read())
for i in range(len(png) // 3, len(png) // 3 + 200):         # garble IDAT, keep IEND
    png[i] ^= 0x5A
open(f"{d}/corrupt_idat.png", "wb").write(png)
cv2.imwrite(f"{d}/small.png", noise[:64, :64])              # source for huge_ihdr.png
cv2.imwrite(f"{d}/one_pixel.png", np.full((1, 1), 128, np.uint8))
flat = np.full((300, 400), 128, np.uint8)
cv2.imwrite(f"{d}/flat.png", flat)
faint = flat.copy()
cv2.rectangle(faint, (120, 80), (280, 220), 131, -1)        # 3 grey levels of contrast
cv2.imwrite(f"{d}/faint_rect.png", faint)
EOF
head -c "$(($(stat -c %s "$D/real.png") / 2))" "$D/real.png" >"$D/truncated.png"
{ cat "$D/truncated.jpg"; printf '\xff\xd9'; } >"$D/truncated_eoi.jpg"
cp "$D/small.png" "$D/huge_ihdr.png"
# IHDR width and height (bytes 16..23, big-endian) := 100000 = 0x000186A0
printf '\x00\x01\x86\xa0\x00\x01\x86\xa0' | dd of="$D/huge_ihdr.png" bs=1 seek=16 conv=notrunc status=none

# name:path of every bad image
BAD_IMAGES=(
  "missing file:$D/no_such_file.png"
  "directory:$D/a_directory.png"
  "empty file:$D/empty.png"
  "text file named .png:$D/text.png"
  "truncated PNG:$D/truncated.png"
  "truncated JPEG:$D/truncated.jpg"
  "1x1 PNG:$D/one_pixel.png"
  "PNG with 100000x100000 IHDR:$D/huge_ihdr.png"
  "PGM declaring 100000x100000:$D/huge.pgm"
)

GOOD_IMG=$SAMPLES/coffee.jpg
MODEL=$T/coffee.mvkp
expect_ok "train quick model: train coffee.jpg --views 20" "$MVKP" train -q "$GOOD_IMG" -o "$MODEL" --views 20
[[ -s $MODEL ]] || { echo "FAIL: no model written, cannot continue"; echo "$passed passed, $((failed + 1)) failed"; exit 1; }

# --- 1. bad images -----------------------------------------------------------

# check_bad_image WHAT IMG: train, pair (either side) and match all reject IMG cleanly.
check_bad_image() {
  local what=$1 img=$2
  expect_fail "train rejects $what" "$img" "$MVKP" train -q "$img" -o "$T/bad.mvkp"
  expect_fail "pair rejects $what as IMG1" "$img" "$MVKP" pair "$img" "$GOOD_IMG" --json
  expect_fail "pair rejects $what as IMG2" "$img" "$MVKP" pair "$GOOD_IMG" "$img" --json
  expect_fail "match rejects $what as query" "$img" "$MVKP" match "$MODEL" "$img"
}
for entry in "${BAD_IMAGES[@]}"; do
  check_bad_image "${entry%%:*}" "${entry#*:}"
done
check "train wrote no model for any bad input" test ! -e "$T/bad.mvkp"

# Found while writing this test and fixed since: strict JPEG/PNG/PNM decoding.
check_bad_image "truncated ASCII PGM (P2)" "$D/truncated_p2.pgm"
check_bad_image "PNG with corrupt IDAT data" "$D/corrupt_idat.png"
check_bad_image "truncated JPEG with an EOI marker appended" "$D/truncated_eoi.jpg"

# --- 1b. targets without texture ---------------------------------------------

for img in "$D/flat.png" "$D/faint_rect.png"; do
  name=$(basename "$img")
  expect_fail "train rejects textureless $name" "too little texture" "$MVKP" train -q "$img" -o "$T/flat.mvkp"
  stderr_has "train $name: message names the file" "$img"
  expect_fail "pair rejects textureless $name as IMG1" "too little texture" "$MVKP" pair "$img" "$GOOD_IMG" --json
  stderr_has "pair $name: message names the file" "$img"
done
check "train wrote no model for a textureless target" test ! -e "$T/flat.mvkp"

# --- 1c. corrupt model files -------------------------------------------------

"$PY" - "$MODEL" "$T" <<'EOF'
import sys, random, struct, zlib
model, t = sys.argv[1], sys.argv[2]
data = bytearray(open(model, "rb").read())
random.seed(3)
open(f"{t}/garbage.mvkp", "wb").write(bytes(random.getrandbits(8) for _ in range(4096)))
open(f"{t}/truncated.mvkp", "wb").write(data[: len(data) // 2])
flipped = bytearray(data); flipped[len(data) // 2] ^= 0xFF
open(f"{t}/flipped.mvkp", "wb").write(flipped)
newer = bytearray(data); newer[8:12] = struct.pack("<I", 99)
open(f"{t}/newer.mvkp", "wb").write(newer)
# Header payload length (bytes 12..19) = 2^64-1.
huge_len = bytearray(data); huge_len[12:20] = struct.pack("<Q", 2**64 - 1)
open(f"{t}/huge_len.mvkp", "wb").write(huge_len)
# Valid checksum, but a descriptor dimension (2000) no 32x32 Walsh-Hadamard basis has.
payload = bytearray(data[20:-4])
nloc = struct.unpack_from("<I", payload, 77)[0]
body = payload[: 81 + 12 * nloc]
struct.pack_into("<i", body, 8, 2000)
body += struct.pack("<I", 10) + b"".join(struct.pack("<i", i) + bytes(4 * 2000) for i in range(10))
open(f"{t}/dims2000.mvkp", "wb").write(
    data[:8] + struct.pack("<IQ", 1, len(body)) + bytes(body) + struct.pack("<I", zlib.crc32(bytes(body))))
EOF
: >"$T/empty.mvkp"
expect_fail "match rejects missing model" "$T/no_such.mvkp" "$MVKP" match "$T/no_such.mvkp" "$GOOD_IMG"
expect_fail "match rejects directory as model" "$D/a_directory.png" "$MVKP" match "$D/a_directory.png" "$GOOD_IMG"
expect_fail "match rejects empty model" "$T/empty.mvkp" "$MVKP" match "$T/empty.mvkp" "$GOOD_IMG"
expect_fail "match rejects image as model" "$GOOD_IMG" "$MVKP" match "$GOOD_IMG" "$GOOD_IMG"
expect_fail "match rejects garbage model" "$T/garbage.mvkp" "$MVKP" match "$T/garbage.mvkp" "$GOOD_IMG"
expect_fail "match rejects truncated model" "$T/truncated.mvkp" "$MVKP" match "$T/truncated.mvkp" "$GOOD_IMG"
expect_fail "match rejects model with a flipped byte" "$T/flipped.mvkp" "$MVKP" match "$T/flipped.mvkp" "$GOOD_IMG"
stderr_has "flipped byte: message mentions the checksum" "checksum"
expect_fail "match rejects model format version 99" "$T/newer.mvkp" "$MVKP" match "$T/newer.mvkp" "$GOOD_IMG"
stderr_has "version 99: message says 'newer'" "newer"
expect_fail "match rejects model with payload length 2^64-1" "$T/huge_len.mvkp" "$MVKP" match "$T/huge_len.mvkp" "$GOOD_IMG"
stderr_lacks "payload length 2^64-1: message gives a sane declared size" "header declares 23)"
expect_fail "match rejects checksummed model with impossible dimension 2000" "$T/dims2000.mvkp" \
  "$MVKP" match "$T/dims2000.mvkp" "$GOOD_IMG"

# --- 1d. bad options ---------------------------------------------------------

expect_reject "train --views 0" "$MVKP" train -q "$GOOD_IMG" -o "$T/opt.mvkp" --views 0
expect_reject "train --kernels 0" "$MVKP" train -q "$GOOD_IMG" -o "$T/opt.mvkp" --kernels 0
expect_reject "pair --views 0" "$MVKP" pair "$GOOD_IMG" "$GOOD_IMG" --views 0
expect_reject "pair --kernels 0" "$MVKP" pair "$GOOD_IMG" "$GOOD_IMG" --kernels 0
expect_reject "match --ratio 2" "$MVKP" match "$MODEL" "$GOOD_IMG" --ratio 2
expect_reject "pair --ratio 2" "$MVKP" pair "$GOOD_IMG" "$GOOD_IMG" --ratio 2
expect_reject "unknown subcommand" "$MVKP" frobnicate
stderr_has "unknown subcommand: message names it" "frobnicate"
expect_reject "no arguments" "$MVKP"
expect_reject "train without -o" "$MVKP" train "$GOOD_IMG"
expect_reject "match without a query" "$MVKP" match "$MODEL"

# --- 2. good paths -----------------------------------------------------------

M=$T/starry.mvkp
expect_ok "train starry_night.jpg --views 40" "$MVKP" train -q "$SAMPLES/starry_night.jpg" -o "$M" --views 40
size=$(stat -c %s "$M" 2>/dev/null || echo 0)
check "starry model written, $size bytes < 1.5 MB (issue 18)" test "$size" -gt 0 -a "$size" -lt 1572864

S=$T/synth
expect_ok "synth starry_night.jpg --n 3 --seed 1" "$MVKP" synth "$SAMPLES/starry_night.jpg" --n 3 --seed 1 -o "$S"
check "synth manifest: 1 comment line + 3 data lines" \
  test "$(grep -c '^#' "$S/manifest.txt" 2>/dev/null)" = 1 -a "$(grep -vc '^#' "$S/manifest.txt" 2>/dev/null)" = 3
check "synth wrote target.png, view_000{0,1,2}.png, H_000{0,1,2}.txt" \
  test -s "$S/target.png" -a -s "$S/view_0000.png" -a -s "$S/view_0001.png" -a -s "$S/view_0002.png" \
  -a -s "$S/H_0000.txt" -a -s "$S/H_0001.txt" -a -s "$S/H_0002.txt"

# The model must be trained on the synth target so coordinates agree with H_*.txt.
TM=$T/target.mvkp
expect_ok "train synth target.png --views 40" "$MVKP" train -q "$S/target.png" -o "$TM" --views 40
expect_ok "match target model on the 3 views --json" "$MVKP" match "$TM" "$S"/view_*.png --json
cp "$T/out" "$T/match.jsonl"

# Validate the JSON lines against the ground truth; prints ok:/FAIL: lines itself.
validate_match() {
  "$PY" - "$T/match.jsonl" "$S" <<'EOF'
import json, sys, os
import cv2, numpy as np
lines = open(sys.argv[1]).read().splitlines()
sdir = sys.argv[2]
def report(good, msg): print(("ok: " if good else "FAIL: ") + msg)
report(len(lines) == 3, f"match --json printed {len(lines)} lines (want 3)")
objs = []
for i, line in enumerate(lines):
    try:
        o = json.loads(line)
        assert isinstance(o, dict)
        objs.append(o)
    except Exception as e:
        report(False, f"match --json line {i} is not a JSON object: {e}: {line[:120]}")
keys = {"query", "found", "homography", "outline", "inliers", "time_ms"}
for o in objs:
    miss = keys - o.keys()
    report(not miss, f"match JSON for {os.path.basename(str(o.get('query')))} has keys {sorted(keys)}"
           + (f" (missing {sorted(miss)})" if miss else ""))
found = [o for o in objs if o.get("found") is True]
report(len(found) >= 2, f"target found in {len(found)} of {len(objs)} views (want >= 2)")
h, w = cv2.imread(os.path.join(sdir, "target.png"), cv2.IMREAD_UNCHANGED).shape[:2]
corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float64)
for o in found:
    q = o["query"]
    n = os.path.basename(q)[len("view_"):-len(".png")]
    H = np.loadtxt(os.path.join(sdir, f"H_{n}.txt")).reshape(3, 3)
    p = np.c_[corners, np.ones(4)] @ H.T
    gt = p[:, :2] / p[:, 2:]
    try:
        out = np.array(o["outline"], np.float64).reshape(4, 2)
    except Exception:
        report(False, f"{os.path.basename(q)}: outline is not 4 points: {o.get('outline')}")
        continue
    err = np.linalg.norm(out - gt, axis=1).mean()
    report(err < 10, f"{os.path.basename(q)}: outline vs ground-truth H mean corner error {err:.2f} px (< 10), {o['inliers']} inliers")
EOF
}
validate_match >"$T/validate" 2>&1
vrc=$?
while IFS= read -r line; do
  case $line in
    ok:\ *) ok "${line#ok: }" ;;
    *) fail "${line#FAIL: }" ;;
  esac
done <"$T/validate"
((vrc == 0)) || fail "match JSON validation script exited $vrc"

expect_ok "pair target.png view_0000.png --json" "$MVKP" pair "$S/target.png" "$S/view_0000.png" --json
"$PY" - "$T/out" >"$T/pair_check" 2>&1 <<'EOF'
import json, sys
lines = open(sys.argv[1]).read().splitlines()
assert len(lines) == 1, f"{len(lines)} stdout lines, want 1"
o = json.loads(lines[0])
for k in ("method", "keypoints1", "keypoints2", "time_ms", "homography", "matches"):
    assert k in o, f"missing key {k}"
assert "query" in o["time_ms"] and "total" in o["time_ms"], f"time_ms lacks query/total: {o['time_ms']}"
H = o["homography"]
assert H is None or (len(H) == 3 and all(len(r) == 3 for r in H)), f"homography not 3x3 or null: {H}"
assert isinstance(o["matches"], list) and o["matches"], "no matches"
for m in o["matches"]:
    assert len(m) == 6 and all(isinstance(v, (int, float)) for v in m), f"bad match entry {m}"
print(f"method={o['method']}, {len(o['matches'])} matches, homography {'3x3' if H else 'null'}")
EOF
prc=$?
if ((prc == 0)); then ok "pair JSON well-formed: $(cat "$T/pair_check")"; else fail "pair JSON: $(tail -n 1 "$T/pair_check")"; fi

expect_ok "match --draw with 2 queries" "$MVKP" match "$TM" "$S/view_0000.png" "$S/view_0001.png" --draw "$T/draw.png"
check "match --draw wrote draw-0.png and draw-1.png as PNG" \
  "$PY" -c 'import sys, cv2; sys.exit(0 if all(cv2.imread(p) is not None and open(p,"rb").read(8)==b"\x89PNG\r\n\x1a\n" for p in sys.argv[1:]) else 1)' \
  "$T/draw-0.png" "$T/draw-1.png"
expect_ok "match --draw with 1 query" "$MVKP" match "$TM" "$S/view_0002.png" --draw "$T/one.png"
check "match --draw wrote one.png as PNG" "$PY" -c 'import sys, cv2; sys.exit(cv2.imread(sys.argv[1]) is None)' "$T/one.png"

# One good and one missing query: a result line, an error line, non-zero exit.
run "$MVKP" match "$TM" "$S/view_0000.png" "$D/no_such_file.png" --json
if why=$(process_problem); then
  fail "match good+missing query: $why"
else
  check "match good+missing query exits non-zero (exit $RC)" test "$RC" -ne 0
  check "match good+missing query: JSON result line then {query, error} line" "$PY" - "$T/out" "$S/view_0000.png" "$D/no_such_file.png" <<'EOF'
import json, sys
lines = open(sys.argv[1]).read().splitlines()
assert len(lines) == 2, lines
a, b = map(json.loads, lines)
assert a["query"] == sys.argv[2] and "found" in a and "error" not in a, a
assert b["query"] == sys.argv[3] and isinstance(b.get("error"), str) and b["error"], b
EOF
  check "match good+missing query: stderr names the missing file" grep -qF "$D/no_such_file.png" "$T/err"
fi

cli_finish "$known KNOWN-BUG lines (reported product bugs, not counted as failures)"
