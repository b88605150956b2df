#!/usr/bin/env bash
# End-to-end tests of the aerial commands (issue 8): `mvkp synth-city` writes
# scenes with ground truth; `mvkp register` puts a generated photo onto its
# depth image within 5 px of the truth (mean corner error), answers "no
# registration found" (exit 0, homography null) for a photo of other ground;
# `mvkp segment` finds the buildings; the real Montpellier tile's nDSM reads
# through GDAL; bad input (missing, non-image, LAZ, flat, all-nodata, absurd
# LAS counts) fails with one clear line and exit 1, never a crash.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples.
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init aerial
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DATA=${MVKP_DATA_DIR:-$HERE/../shared/data}

expect_ok "synth-city: 6 scenes" "$MVKP" synth-city -o "$T/c" --n 6 --seed 7
check "synth-city: depth, photo, truth and ids written" test -s "$T/c/city_0000/depth.tif" -a -s "$T/c/city_0000/photo.png" \
  -a -s "$T/c/city_0000/truth.json" -a -s "$T/c/city_0001/building_id.png"
expect_ok "synth-city: a scene of other ground" "$MVKP" synth-city -o "$T/n" --n 1 --seed 8 --no-overlap

# Register each generated scene; score against the truth.
score() { # score SCENE_DIR JSON -> prints "ok <mean corner error>" or "no"
  "$PY" - "$1" "$2" <<'PYEOF'
import json, sys
import numpy as np
t = json.load(open(sys.argv[1] + "/truth.json"))
j = json.load(open(sys.argv[2]))
if not j["ok"]:
    print("no"); sys.exit()
He, Ht = np.array(j["homography"]), np.array(t["photo_to_depth"])
c = np.array(t["corners"], float)
p = np.c_[c, np.ones(len(c))] @ np.linalg.inv(Ht).T
p = p[:, :2] / p[:, 2:]
w, h = t["photo_size"]
v = (p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1)
q = np.c_[p[v], np.ones(v.sum())] @ He.T
print("ok %.3f" % np.linalg.norm(q[:, :2] / q[:, 2:] - c[v], axis=1).mean())
PYEOF
}
good=0
for s in 0 1 2 3 4 5; do
  d=$T/c/city_000$s
  run "$MVKP" register "$d/depth.tif" "$d/photo.png" --json --draw "$T/reg$s.png"
  if why=$(process_problem); then fail "register scene $s: $why"; continue; fi
  cp "$T/out" "$T/reg$s.json"
  r=$(score "$d" "$T/reg$s.json")
  echo "scene $s: $r ($(grep -o '"reason":"[^"]*"' "$T/reg$s.json"))"
  case $r in ok\ *) awk -v e="${r#ok }" 'BEGIN{exit !(e <= 5)}' && good=$((good + 1)) || fail "register scene $s: WRONG registration reported as success ($r)";; esac
done
check "register: generated scenes within 5 px: $good of 6 (at least ${MIN_GOOD:=4}), none wrong" test $good -ge "$MIN_GOOD"
check "register --draw wrote a drawing" test -s "$T/reg0.png"
check "register --json: the correspondence JSON with per-stage times" "$PY" -c "
import json; j = json.load(open('$T/reg0.json'))
assert j['method'] == 'mvkp-register' and 'matches' in j and 'region_matches' in j
assert all(k in j['time_ms'] for k in ('read', 'segment_depth', 'segment_photo', 'match', 'propagate', 'total'))"
check "register --json: the image evidence (outline edge contrast) of the registered scenes" "$PY" -c "
import json
js = [json.load(open('$T/reg%d.json' % s)) for s in range(6)]
oks = [j for j in js if j['ok']]
assert oks and all(j['edge'] is None or j['edge']['contrast'] > 0 for j in oks)
assert any(j['edge'] and j['edge']['contrast'] >= 1.8 and j['edge']['points'] >= 60 for j in oks)"
run "$MVKP" register "$T/c/city_0000/depth.tif" "$T/c/city_0000/photo.png" --json --min-edge-contrast 0 --no-edge-refine
check "register --min-edge-contrast 0: no image evidence in the answer" "$PY" -c "
import json; j = json.load(open('$T/out')); assert j['edge'] is None"

d=$T/n/city_0000
expect_ok "register a photo of other ground: exit 0" "$MVKP" register "$d/depth.tif" "$d/photo.png" --json
check "... with no registration (homography null, a reason)" "$PY" -c "
import json; j = json.loads(open('$T/out').read())
assert j['ok'] is False and j['homography'] is None and j['reason'].startswith('no registration found'), j['reason']"

# Issue 21: the second method on a small tile with 4 buildings (seed 1, scene 6
# of synth-city --buildings 4 --width 200 --height 200), and which method answered.
expect_ok "synth-city: small tiles" "$MVKP" synth-city -o "$T/s" --n 7 --seed 1 --buildings 4 --width 200 --height 200
expect_ok "register --method outlines: exit 0" "$MVKP" register "$T/s/city_0006/depth.tif" "$T/s/city_0006/photo.png" \
  --json --method outlines
check "... registered by the outline search within 5 px, with a confidence" "$PY" -c "
import json, numpy as np
j = json.load(open('$T/out')); t = json.load(open('$T/s/city_0006/truth.json'))
assert j['ok'] and j['registration_method'] == 'outlines' and 0.5 <= j['confidence'] <= 1, j['reason']
assert j['method'] == 'mvkp-register' and j['outline_search']['ok'] and j['time_ms']['outline_search'] > 0
H, Ht = np.array(j['homography']), np.array(t['photo_to_depth'])
c = np.array(t['corners'], float).reshape(-1, 2); p = np.c_[c, np.ones(len(c))] @ np.linalg.inv(Ht).T; p = p / p[:, 2:]
w, h = t['photo_size']; v = (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
q = p[v] @ H.T; e = np.linalg.norm(q[:, :2] / q[:, 2:] - c[v], axis=1).mean(); assert e <= 5, e"
run "$MVKP" register "$T/s/city_0006/depth.tif" "$T/s/city_0006/photo.png" --json --method regions
check "register --method regions: no outline search" "$PY" -c "
import json; j = json.load(open('$T/out')); assert j['outline_search'] is None
assert j['registration_method'] in (None, 'regions') and (j['ok'] or j['confidence'] == 0)"
expect_ok "register other ground --method outlines: exit 0" "$MVKP" register "$T/n/city_0000/depth.tif" \
  "$T/n/city_0000/photo.png" --json --method outlines
check "... no registration, confidence 0" "$PY" -c "
import json; j = json.load(open('$T/out'))
assert not j['ok'] and j['registration_method'] is None and j['confidence'] == 0 and j['outline_search'] is not None"

# Issue 21: a conventional (leaning) orthophoto. Dense town blocks of many
# heights: the answer maps the ground, with the lean it estimated. Counted
# over scenes (clang's builds draw other scenes than GCC's).
expect_ok "synth-city --style dense: 4 scenes" "$MVKP" synth-city -o "$T/lean" --n 4 --seed 3 --style dense
for s in 0 1 2 3; do
  run "$MVKP" register "$T/lean/city_000$s/depth.tif" "$T/lean/city_000$s/photo.png" --json
  cp "$T/out" "$T/lean$s.json"
done
check "register, leaning photos: registered ones within 5 px, lean near the truth when estimated" "$PY" -c "
import json, numpy as np
n_ok = n_lean = 0
for s in range(4):
    j = json.load(open('$T/lean%d.json' % s)); t = json.load(open('$T/lean/city_000%d/truth.json' % s))
    if not j['ok']:
        assert j['lean_depth_px_per_m'] is None; continue
    n_ok += 1
    H, Ht = np.array(j['homography']), np.array(t['photo_to_depth'])
    c = np.array(t['corners'], float).reshape(-1, 2); p = np.c_[c, np.ones(len(c))] @ np.linalg.inv(Ht).T; p = p / p[:, 2:]
    w, h = t['photo_size']; v = (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
    q = p[v] @ H.T; e = np.linalg.norm(q[:, :2] / q[:, 2:] - c[v], axis=1).mean(); assert e <= 5, (s, e)
    est = np.array(j['lean_depth_px_per_m']) * t['res_m']
    if np.any(est != 0):
        n_lean += 1
        assert np.linalg.norm(est - np.array(t['lean_m_per_m'])) < 0.1, (s, est, t['lean_m_per_m'])
assert n_ok >= 2 and n_lean >= 1, (n_ok, n_lean)"

expect_ok "segment depth --json" "$MVKP" segment depth "$T/c/city_0000/depth.tif" --json --draw "$T/segd.png"
check "segment depth: most of the 30 buildings" "$PY" -c "
import json; n = len(json.loads(open('$T/out').read())['regions']); assert 24 <= n <= 40, n"
expect_ok "segment optical" "$MVKP" segment optical "$T/c/city_0000/photo.png" --draw "$T/sego.png"

if [[ -f $DATA/aerial/montpellier/ndsm_50cm.tif ]]; then
  expect_ok "segment depth on the real nDSM (GeoTIFF via GDAL)" "$MVKP" segment depth "$DATA/aerial/montpellier/ndsm_50cm.tif" --json
  check "... finds the long building" "$PY" -c "
import json; r = json.loads(open('$T/out').read())['regions']; assert r and max(x['area_px'] for x in r) > 800, r"
  expect_ok "register the real tile: an answer, not an error" "$MVKP" register "$DATA/aerial/montpellier/ndsm_50cm.tif" \
    "$DATA/aerial/montpellier/ortho_rgb_20cm.tif" --json
  expect_fail "LAZ: decompress first" "decompress" "$MVKP" register "$DATA/aerial/montpellier/lidar.laz" "$SAMPLES/fruits.jpg"
else
  echo "skip: no $DATA/aerial/montpellier"
fi

# The photo segmentation's models, fitted for a dataset and used.
"$PY" -c "
import cv2, numpy as np
p = cv2.imread('$T/c/city_0002/photo.png')
cv2.imwrite('$T/mask.png', np.full(p.shape[:2], 255, np.uint8))"
expect_ok "ortho-models fit-fbm PHOTO=MASK" "$MVKP" ortho-models fit-fbm "$T/c/city_0002/photo.png=$T/mask.png" -o "$T/fbm.json"
check "... a valid model (0 < H < 1, k > 0)" "$PY" -c "
import json; j = json.loads(open('$T/out').read()); assert 0 < j['H'] < 1 and j['k'] > 0, j"
expect_ok "ortho-models train-lda" "$MVKP" ortho-models train-lda -o "$T/lda.json"
expect_ok "register with --fbm and --lda" "$MVKP" register "$T/c/city_0002/depth.tif" "$T/c/city_0002/photo.png" \
  --fbm "$T/fbm.json" --lda "$T/lda.json" --json
expect_fail "fit-fbm without a mask" "PHOTO=MASK" "$MVKP" ortho-models fit-fbm "$T/c/city_0002/photo.png" -o "$T/x.json"
expect_fail "an LDA file given as the fBm model" "fbm" "$MVKP" register "$T/c/city_0002/depth.tif" \
  "$T/c/city_0002/photo.png" --fbm "$T/lda.json"

# Bad input.
expect_fail "missing depth file" "nope.tif" "$MVKP" register "$T/nope.tif" "$SAMPLES/fruits.jpg"
expect_fail "missing photo" "nope.png" "$MVKP" register "$T/c/city_0000/depth.tif" "$T/nope.png"
printf 'not an image at all' >"$T/junk.png"
expect_fail "non-image photo" "junk.png" "$MVKP" register "$T/c/city_0000/depth.tif" "$T/junk.png"
expect_fail "a photo as the depth image" "looks like a photo" "$MVKP" register "$SAMPLES/fruits.jpg" "$T/c/city_0000/photo.png"
"$PY" - "$T" <<'PYEOF'
import sys, numpy as np, cv2, struct
t = sys.argv[1]
cv2.imwrite(t + "/flat.tif", np.full((200, 200), 5.0, np.float32))
cv2.imwrite(t + "/nan.tif", np.full((200, 200), np.nan, np.float32))
# A LAS 1.2 header claiming 10^9 points in a 400-byte file.
h = bytearray(227)
h[0:4] = b"LASF"; h[24] = 1; h[25] = 2
struct.pack_into("<H", h, 94, 227); struct.pack_into("<I", h, 96, 227); h[104] = 0
struct.pack_into("<H", h, 105, 20); struct.pack_into("<I", h, 107, 10**9)
struct.pack_into("<ddd", h, 131, 0.01, 0.01, 0.01)
open(t + "/huge.las", "wb").write(bytes(h) + b"\0" * 173)
PYEOF
for bad in "--outline-completeness 5" "--outline-object-weight 2"; do
  # shellcheck disable=SC2086  # the option and its value as two words
  run "$MVKP" register "$T/c/city_0000/depth.tif" "$T/c/city_0000/photo.png" $bad
  if ((RC == 2)) && grep -qF -- "${bad% *}" "$T/err"; then
    ok "register $bad is a usage error"
  else
    fail "register $bad: exit $RC: $(first_err)"
  fi
done
expect_fail "flat depth" "flat" "$MVKP" register "$T/flat.tif" "$T/c/city_0000/photo.png"
expect_fail "depth with no data anywhere" "no data" "$MVKP" segment depth "$T/nan.tif"
expect_fail "LAS header claiming 10^9 points" "huge.las" "$MVKP" segment depth "$T/huge.las"
expect_fail "synth-city --n 0" "--n" "$MVKP" synth-city -o "$T/z" --n 0

# synth-oblique (issue 22): a city with two oblique views and their ground truth;
# the camera reprojects every check point to its oblique pixel, and a nadir
# pixel lifted through the truth lands on its world point for open ground.
expect_ok "synth-oblique: 1 city, 2 views" "$MVKP" synth-oblique -o "$T/o" --n 1 --views 2 --seed 3 --style dense \
  --width 480 --height 360
check "synth-oblique: views and truth written" test -s "$T/o/city_0000/oblique_00.png" -a -s "$T/o/city_0000/oblique_01.json" \
  -a -s "$T/o/city_0000/truth.json"
check "synth-oblique: camera reprojects the check points" "$PY" - "$T/o/city_0000/oblique_00.json" <<'PYEOF'
import json, sys
import numpy as np
v = json.load(open(sys.argv[1]))
P = np.array(v["camera"])
cps = v["check_points"]
assert len(cps) >= 20, len(cps)
X = np.array([c["world_m"] + [1] for c in cps]) @ P.T
err = np.abs(X[:, :2] / X[:, 2:] - np.array([c["oblique_px"] for c in cps])).max()
assert err < 1e-6, err
assert 30 <= v["options"]["tilt_deg"] <= 60
PYEOF
expect_fail "synth-oblique --tilt 80 90" "--tilt" "$MVKP" synth-oblique -o "$T/oz" --tilt 80 90

# register-all / register-view (issue 22): the oblique views' cameras through
# stage 1 (here the city's true nadir -> depth registration, written as mvkp
# register's JSON). An answer must reproject the check points within 5 px
# (never wrong); MVKP on the nadir photo's tiles finds most views, so at least
# two of four must be answered, and a view of other ground gets no camera.
# (Called directly, not through `run`: training the tiles takes 10-20 s here.)
expect_ok "synth-oblique: 4 views for register-all" "$MVKP" synth-oblique -o "$T/rv" --n 1 --views 4 --seed 2 \
  --style dense --tilt 35 50 --gsd 0.25 0.4
expect_ok "synth-oblique: a view of other ground" "$MVKP" synth-oblique -o "$T/rvo" --n 1 --views 1 --seed 5 --style suburb
RV="$T/rv/city_0000"
OTHER="$T/rvo/city_0000/oblique_00.png"
"$PY" - "$RV" <<'PYEOF'
import json, sys
d = sys.argv[1]
t = json.load(open(d + "/truth.json"))
lean = [x / t["res_m"] for x in t.get("lean_m_per_m", [0, 0])]
s1 = {"homography": t["photo_to_depth"], "lean_depth_px_per_m": lean,
      "depth": {"size": t["depth_size"], "res_m": t["res_m"]}, "photo": {"size": t["photo_size"]}}
json.dump(s1, open(d + "/stage1.json", "w"))
s1["depth"]["size"] = [123, 45]
json.dump(s1, open(d + "/stage1_other.json", "w"))
s1["homography"] = None
json.dump(s1, open(d + "/stage1_none.json", "w"))
PYEOF
if "$MVKP" register-all "$RV/depth.tif" "$RV/photo.png" "$RV"/oblique_0{0,1,2,3}.png "$OTHER" --stage1 "$RV/stage1.json" \
    --json --draw-dir "$T/rvdraw" > "$T/rall.json" 2> "$T/err"; then
  ok "register-all: 4 views and one of other ground, exit 0"
  check "register-all: cameras within 5 px, at least 2 of 4, none for other ground" "$PY" - "$T/rall.json" "$RV" <<'PYEOF'
import json, sys
import numpy as np
j = json.load(open(sys.argv[1]))
assert j["stage1"]["ok"] and len(j["views"]) == 5, j["stage1"]
answered = 0
for k, r in enumerate(j["views"][:4]):
    v = json.load(open("%s/oblique_%02d.json" % (sys.argv[2], k)))
    if not r["ok"]:
        assert r["camera"] is None and r["reason"].startswith("no registration"), r["reason"]
        continue
    P = np.array(r["camera"])
    X = np.array([c["world_m"] + [1] for c in v["check_points"]]) @ P.T
    e = np.linalg.norm(X[:, :2] / X[:, 2:] - np.array([c["oblique_px"] for c in v["check_points"]]), axis=1).mean()
    assert e <= 5, "view %d: camera %.1f px off" % (k, e)
    H = np.array(r["homography"])  # nadir -> view for the ground plane: finite, invertible
    assert np.isfinite(H).all() and abs(np.linalg.det(H)) > 1e-12
    answered += 1
assert answered >= 2, "only %d of 4 views answered" % answered
o = j["views"][4]
assert not o["ok"] and o["camera"] is None, o["reason"]
print("answered", answered)
PYEOF
  check "register-all --draw-dir: a drawing per view" test -s "$T/rvdraw/oblique_00-registered.jpg" -a \
    -s "$T/rvdraw/oblique_03-registered.jpg"
else
  fail "register-all exits 0 ($(first_err))"
fi
# --method fusion (thesis 7.3.2) and auto: answers right or none, none for
# other ground; auto answers at least what mvkp answered (it runs fusion only
# for the views mvkp finds no camera for).
for method in fusion auto; do
  if "$MVKP" register-all "$RV/depth.tif" "$RV/photo.png" "$RV"/oblique_0{0,1,2,3}.png "$OTHER" \
      --stage1 "$RV/stage1.json" --json --method $method > "$T/rall-$method.json" 2> "$T/err"; then
    check "register-all --method $method: cameras within 5 px or none, none for other ground" "$PY" - \
        "$T/rall-$method.json" "$RV" "$method" "$T/rall.json" <<'PYEOF'
import json, sys
import numpy as np
j = json.load(open(sys.argv[1]))
method = sys.argv[3]
base = json.load(open(sys.argv[4]))["views"]
assert len(j["views"]) == 5
for k, r in enumerate(j["views"]):
    assert r["requested_method"] == method, r
    if method == "fusion" or not base[k]["ok"]:
        assert r["fusion"]["ms"] > 0 and "nadir_regions" in r["fusion"], r.get("fusion")
    if not r["ok"]:
        assert r["camera"] is None and r["reason"].startswith("no registration"), r["reason"]
        assert k == 4 or method == "fusion" or not base[k]["ok"], "auto lost view %d" % k
        continue
    assert k < 4, "a camera for other ground: " + r["reason"]
    assert r["method"] == ("fusion-pnp" if method == "fusion" or not base[k]["ok"] else "mvkp-pnp"), r["method"]
    v = json.load(open("%s/oblique_%02d.json" % (sys.argv[2], k)))
    X = np.array([c["world_m"] + [1] for c in v["check_points"]]) @ np.array(r["camera"]).T
    e = np.linalg.norm(X[:, :2] / X[:, 2:] - np.array([c["oblique_px"] for c in v["check_points"]]), axis=1).mean()
    assert e <= 5, "view %d: camera %.1f px off (%s)" % (k, e, r["method"])
print(method, "answered", sum(r["ok"] for r in j["views"]))
PYEOF
  else
    fail "register-all --method $method exits 0 ($(first_err))"
  fi
done
run "$MVKP" register-view "$RV/depth.tif" "$RV/photo.png" "$RV/stage1.json" "$RV/oblique_00.png" --method sift
if ((RC == 2)) && grep -qF -- "--method" "$T/err"; then
  ok "register-view: --method sift is a usage error"
else
  fail "register-view --method sift: exit $RC: $(first_err)"
fi
# register-all runs stage 1 itself (as mvkp register) and saves it
if "$MVKP" register-all "$RV/depth.tif" "$RV/photo.png" "$RV/oblique_01.png" --res 0.5 --save-stage1 "$T/s1.json" \
    --json > "$T/rall1.json" 2> "$T/err"; then
  check "register-all: stage 1 run and saved, the view answered or refused" "$PY" -c '
import json, sys
s = json.load(open(sys.argv[1])); j = json.load(open(sys.argv[2]))
assert j["stage1"]["ok"] == (s["homography"] is not None), j["stage1"]
v = j["views"][0]
assert (v["camera"] is not None) == v["ok"], v["reason"]' "$T/s1.json" "$T/rall1.json"
else
  fail "register-all with stage 1 exits 0 ($(first_err))"
fi
# register-view gives the same answer for a view as register-all
if "$MVKP" register-view "$RV/depth.tif" "$RV/photo.png" "$RV/stage1.json" "$RV/oblique_02.png" --json \
    > "$T/rv_02.json" 2> "$T/err"; then
  check "register-view: the same camera as register-all" "$PY" -c '
import json, sys
a = json.load(open(sys.argv[1])); b = json.load(open(sys.argv[2]))["views"][2]
assert a["ok"] == b["ok"] and a["camera"] == b["camera"], (a["reason"], b["reason"])' "$T/rv_02.json" "$T/rall.json"
else
  fail "register-view exits 0 ($(first_err))"
fi
# A stage 1 that puts the nadir photo 5 depth px (2.5 m) off, as a real
# stage-1 error would: every camera through it is 6-8 px off. The LiDAR's
# outlines must replace them, and register-all must then correct stage 1
# from those views and register all four again through it.
"$PY" - "$RV" <<'PYEOF'
import json, sys
import numpy as np
d = sys.argv[1]
s1 = json.load(open(d + "/stage1.json"))
s1["homography"] = (np.array([[1, 0, 4.0], [0, 1, -3.0], [0, 0, 1]]) @ np.array(s1["homography"])).tolist()
json.dump(s1, open(d + "/stage1_shifted.json", "w"))
PYEOF
if "$MVKP" register-all "$RV/depth.tif" "$RV/photo.png" "$RV"/oblique_0{0,1,2,3}.png --stage1 "$RV/stage1_shifted.json" \
    --json > "$T/rshift.json" 2> "$T/err"; then
  check "register-all: a displaced stage 1 is corrected by the views, cameras within 2 px" "$PY" - "$T/rshift.json" "$RV" <<'PYEOF'
import json, sys
import numpy as np
j = json.load(open(sys.argv[1]))
c = j["stage1"]["correction"]
assert c["applied"] and c["inliers"] >= 30, c
C = np.array(c["correction"])
assert abs(C[0, 2] + 4) < 0.6 and abs(C[1, 2] - 3) < 0.6, C  # the shift undone, depth px
answered = 0
for k, r in enumerate(j["views"]):
    if not r["ok"]:
        continue
    v = json.load(open("%s/oblique_%02d.json" % (sys.argv[2], k)))
    P = np.array(r["camera"])
    X = np.array([q["world_m"] + [1] for q in v["check_points"]]) @ P.T
    e = np.linalg.norm(X[:, :2] / X[:, 2:] - np.array([q["oblique_px"] for q in v["check_points"]]), axis=1).mean()
    assert e <= 2, "view %d: camera %.1f px off" % (k, e)
    answered += 1
assert answered >= 2, "only %d of 4 views answered" % answered
print("answered", answered)
PYEOF
else
  fail "register-all with a displaced stage 1 exits 0 ($(first_err))"
fi
expect_fail "register-view: stage 1 without a registration" "no registration" "$MVKP" register-view \
  "$RV/depth.tif" "$RV/photo.png" "$RV/stage1_none.json" "$RV/oblique_00.png"
expect_fail "register-view: stage 1 of another depth raster" "does not match" "$MVKP" register-view \
  "$RV/depth.tif" "$RV/photo.png" "$RV/stage1_other.json" "$RV/oblique_00.png"
expect_fail "register-view: stage 1 not JSON" "not JSON" "$MVKP" register-view \
  "$RV/depth.tif" "$RV/photo.png" "$RV/photo.png" "$RV/oblique_00.png"
expect_fail "register-view: a view that is not an image" "oblique_00.json" "$MVKP" register-view \
  "$RV/depth.tif" "$RV/photo.png" "$RV/stage1.json" "$RV/oblique_00.json"
expect_fail "register-all: a missing view" "nope.png" "$MVKP" register-all \
  "$RV/depth.tif" "$RV/photo.png" "$RV/oblique_00.png" "$RV/nope.png" --stage1 "$RV/stage1.json"
expect_fail "register-all: stage 1 of another depth raster" "does not match" "$MVKP" register-all \
  "$RV/depth.tif" "$RV/photo.png" "$RV/oblique_00.png" --stage1 "$RV/stage1_other.json"
run "$MVKP" register-all "$RV/depth.tif" "$RV/photo.png" "$RV/oblique_00.png" --stage1 "$RV/stage1.json" \
  --max-height-step -1
if ((RC == 2)) && grep -qF -- "--max-height-step" "$T/err"; then
  ok "register-all: a negative height step is a usage error"
else
  fail "register-all: a negative height step: exit $RC: $(first_err)"
fi
expect_ok "register-all: stage 1 without a registration answers no camera" "$MVKP" register-all \
  "$RV/depth.tif" "$RV/photo.png" "$RV/oblique_00.png" --stage1 "$RV/stage1_none.json" --json
check "register-all: no stage 1, no camera" "$PY" -c \
  'import json,sys; j=json.load(open(sys.argv[1])); v=j["views"][0]; assert not j["stage1"]["ok"] and v["camera"] is None and v["reason"].startswith("no registration"), j' "$T/out"

cli_finish
