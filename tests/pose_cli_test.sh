#!/usr/bin/env bash
# End-to-end tests of the target pose (`--camera`, `--width-m`) of `mvkp
# recognize` and `mvkp video`: views rendered through a known camera at known
# poses are recognised with the right rotation and translation in metres
# (width from the target's metadata, else --width-m, else no pose), a camera
# file for a larger frame is rescaled, the text and drawing outputs show it, a
# video's distances follow its scale, and bad camera files or widths fail
# cleanly before any query.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples; needs
# /usr/bin/python3 with numpy and cv2 (scripts/install-deps.sh) for the views.
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init pose
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

DB=$T/pose.db
expect_ok "db create" "$MVKP" db create "$DB"
expect_ok "db add starry with width_m 0.5" "$MVKP" db add "$DB" --id starry --image "$SAMPLES/starry_night.jpg" \
  --title "The Starry Night" --meta '{"width_m": 0.5}'
expect_ok "db add astronaut without a width" "$MVKP" db add "$DB" --id astro --image "$SAMPLES/astronaut.jpg"

# fx = fy = 500, 640x480, no distortion, as OpenCV's calibration sample writes it.
calib() { # calib FILE WIDTH HEIGHT F CX CY
  cat >"$1" <<EOF
%YAML:1.0
---
calibration_time: "test"
image_width: $2
image_height: $3
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ $4, 0., $5, 0., $4, $6, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
avg_reprojection_error: 0.3
EOF
}
calib "$T/calib.yml" 640 480 500. 319.5 239.5
calib "$T/calib2x.yml" 1280 960 1000. 639.5 479.5  # the same camera calibrated at twice the size

# Views through that camera: K [r1 r2 t] S maps target pixels to frame pixels (S: pixels -> metres, centre
# origin, as src/mvkp/pose/pose.h defines). view_a: starry alone; view_b: starry and the astronaut (0.4 m wide).
$PY - "$SAMPLES" "$T" <<'PYEOF' || fail "could not render the views"
import json, sys
import cv2
import numpy as np
samples, out = sys.argv[1:3]
K = np.array([[500, 0, 319.5], [0, 500, 239.5], [0, 0, 1.0]])
bg = cv2.resize(cv2.imread(samples + "/fruits.jpg"), (640, 480))
def place(frame, name, width_m, rvec, t):
    img = cv2.imread(samples + "/" + name)
    h, w = img.shape[:2]
    s = width_m / w
    S = np.array([[s, 0, -(w - 1) / 2 * s], [0, s, -(h - 1) / 2 * s], [0, 0, 1]])
    R, _ = cv2.Rodrigues(np.array(rvec, float))
    H = K @ np.column_stack([R[:, 0], R[:, 1], t]) @ S
    cv2.warpPerspective(img, H, (640, 480), dst=frame, borderMode=cv2.BORDER_TRANSPARENT)
    return {"R": R.tolist(), "t": list(t)}
truth = {}
a = bg.copy()
truth["a"] = {"starry": place(a, "starry_night.jpg", 0.5, [0.3, -0.2, 0.15], [0.04, -0.03, 0.9])}
b = bg.copy()
truth["b"] = {"starry": place(b, "starry_night.jpg", 0.5, [-0.3, 0.35, -0.1], [-0.32, 0.0, 1.2]),
              "astro": place(b, "astronaut.jpg", 0.4, [0.2, -0.4, 0.05], [0.25, 0.04, 0.9])}
cv2.imwrite(out + "/view_a.png", a)
cv2.imwrite(out + "/view_b.png", b)
json.dump(truth, open(out + "/truth.json", "w"))
PYEOF

# check_poses DESC OUT_FILE WANT: WANT maps view -> target -> "pose" | "none"; a pose must be within 2 % of the
# true translation and 3 degrees of the true rotation (the tilt of a 200-px target is the least certain), with
# R = Rodrigues(rvec), |tvec| = distance_m and a small reprojection error; every existing field is still there.
check_poses() {
  check "$1" $PY - "$2" "$T/truth.json" "$3" <<'PYEOF'
import json, sys
import cv2
import numpy as np
lines = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
truth = json.load(open(sys.argv[2]))
want = json.loads(sys.argv[3])
ok = len(lines) == len(want)
for j in lines:
    v = j["query"].rsplit("view_", 1)[1][0]
    found = {f["id"]: f for f in j["found"]}
    for tid, w in want[v].items():
        f = found.get(tid)
        if f is None:
            print(f"view_{v}: {tid} not found"); ok = False; continue
        ok = ok and all(k in f for k in ("id", "title", "homography", "outline", "inliers", "votes", "score"))
        if w == "none":
            ok = ok and "pose" not in f
            print(f"view_{v}: {tid} without pose" + (" (but has one)" if "pose" in f else ""))
            continue
        if "pose" not in f:
            print(f"view_{v}: {tid}: no pose"); ok = False; continue
        p = f["pose"]
        t, tt = np.array(p["tvec"]), np.array(truth[v][tid]["t"])
        R, Rt = np.array(p["R"]), np.array(truth[v][tid]["R"])
        dt = np.linalg.norm(t - tt) / np.linalg.norm(tt)
        da = np.degrees(np.linalg.norm(cv2.Rodrigues(Rt.T @ R)[0]))
        Rr = cv2.Rodrigues(np.array(p["rvec"], float))[0]
        consistent = np.abs(Rr - R).max() < 1e-6 and abs(np.linalg.norm(t) - p["distance_m"]) < 1e-6
        print(f"view_{v}: {tid} t {np.round(t, 3)} (true {tt}), translation off {100 * dt:.2f} %, rotation off "
              f"{da:.2f} deg, reprojection {p['reprojection_px']:.2f} px")
        ok = ok and t[2] > 0 and dt < 0.02 and da < 3 and 0 <= p["reprojection_px"] < 3 and consistent
sys.exit(0 if ok else 1)
PYEOF
}

expect_ok "recognize --camera (JSON)" "$MVKP" recognize "$DB" "$T/view_a.png" "$T/view_b.png" --json \
  --camera "$T/calib.yml"
check_poses "poses near the truth; the astronaut (no width) without one" "$T/out" \
  '{"a": {"starry": "pose"}, "b": {"starry": "pose", "astro": "none"}}'
cp "$T/out" "$T/pose_640.json"

expect_ok "recognize --camera --width-m 0.4 (JSON)" "$MVKP" recognize "$DB" "$T/view_a.png" "$T/view_b.png" \
  --json --camera "$T/calib.yml" --width-m 0.4
check_poses "--width-m gives the astronaut its pose; starry keeps its metadata width" "$T/out" \
  '{"a": {"starry": "pose"}, "b": {"starry": "pose", "astro": "pose"}}'

expect_ok "recognize with a camera calibrated at 1280x960" "$MVKP" recognize "$DB" "$T/view_a.png" "$T/view_b.png" \
  --json --camera "$T/calib2x.yml"
check "the rescaled camera gives the same poses" $PY -c "
import json, sys
a = [json.loads(l) for l in open('$T/pose_640.json')]
b = [json.loads(l) for l in open('$T/out')]
d = max(abs(x - y) for ja, jb in zip(a, b) for fa, fb in zip(ja['found'], jb['found']) if 'pose' in fa
        for x, y in zip(fa['pose']['tvec'], fb['pose']['tvec']))
print('largest tvec difference %.2g m' % d)
sys.exit(0 if len(a) == len(b) == 2 and d < 1e-6 else 1)"

expect_ok "recognize without --camera (JSON)" "$MVKP" recognize "$DB" "$T/view_a.png" --json
check "without --camera: no pose field" $PY -c "
import json, sys
j = json.loads(open('$T/out').read())
sys.exit(0 if j['found'] and all('pose' not in f for f in j['found']) else 1)"

expect_ok "recognize --camera, text mode, --draw" "$MVKP" recognize "$DB" "$T/view_a.png" --camera "$T/calib.yml" \
  --draw "$T/draw.png"
check "text: the distance in metres" \
  grep -qE 'view_a.png: starry "The Starry Night" \([0-9]+ inliers of [0-9]+ votes, distance 0\.90 m\)' "$T/out"
check "--draw with axes written" test -s "$T/draw.png"

# Video: make-test-video.py scales the 300-px target by sc = 0.9 + 0.4 sin(pi t); the database image is 400 px
# wide for 0.5 m, so the distance is close to 500 * 0.5 / (300 sc).
$PY "$HERE/scripts/make-test-video.py" "$SAMPLES/starry_night.jpg" "$SAMPLES/fruits.jpg" "$T/clip.avi" 20 ||
  fail "could not generate the clip"
expect_ok "video --camera --json" "$MVKP" video "$DB" "$T/clip.avi" --json --camera "$T/calib.yml" -o "$T/clip.mp4"
check "video: a pose in every frame, distance from the target's scale within 5 %" $PY - "$T/out" <<'PYEOF'
import json, math, sys
frames = [json.loads(l) for l in open(sys.argv[1]) if '"frame"' in l]
ok = len(frames) == 20
worst = 0
for f in frames:
    sc = 0.9 + 0.4 * math.sin(math.pi * f["frame"] / 19)
    hit = [x for x in f["found"] if x["id"] == "starry" and "pose" in x]
    if not hit:
        ok = False
        continue
    p = hit[0]["pose"]
    err = abs(p["distance_m"] / (500 * 0.5 / (300 * sc)) - 1)
    worst = max(worst, err)
    ok = ok and p["tvec"][2] > 0 and err < 0.05
print(f"{len(frames)} frames, worst distance error {100 * worst:.1f} %")
sys.exit(0 if ok else 1)
PYEOF
check "annotated video with axes written" test -s "$T/clip.mp4"

# Bad input: one line on stderr, exit 1, nothing processed.
expect_fail "missing camera file" "$T/none.yml" "$MVKP" recognize "$DB" "$T/view_a.png" --camera "$T/none.yml"
printf 'not: [a calibration\n' >"$T/junk.yml"
expect_fail "junk camera file" "not an OpenCV calibration file" "$MVKP" recognize "$DB" "$T/view_a.png" --json \
  --camera "$T/junk.yml"
check "junk camera file: no query processed" test ! -s "$T/out"
cp "$SAMPLES/fruits.jpg" "$T/image.yml"
expect_fail "an image as camera file" "$T/image.yml" "$MVKP" recognize "$DB" "$T/view_a.png" --camera "$T/image.yml"
calib "$T/neg.yml" 640 480 -500. 319.5 239.5
expect_fail "negative focal length" "focal" "$MVKP" recognize "$DB" "$T/view_a.png" --camera "$T/neg.yml"
printf '%%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n' >"$T/nok.yml"
expect_fail "no camera_matrix" "camera_matrix" "$MVKP" recognize "$DB" "$T/view_a.png" --camera "$T/nok.yml"
expect_fail "video: junk camera file" "$T/junk.yml" "$MVKP" video "$DB" "$T/clip.avi" --camera "$T/junk.yml"
expect_fail "--width-m without --camera" "--width-m needs --camera" "$MVKP" recognize "$DB" "$T/view_a.png" \
  --width-m 0.4
expect_fail "--width-m 0" "--width-m" "$MVKP" recognize "$DB" "$T/view_a.png" --camera "$T/calib.yml" --width-m 0
calib "$T/wide.yml" 1280 720 900. 639.5 359.5
expect_fail "camera of another aspect ratio than the frame" "aspect ratio" "$MVKP" recognize "$DB" "$T/view_a.png" \
  --camera "$T/wide.yml"
expect_ok "db add a target with a bad width_m" "$MVKP" db add "$DB" --id building --image "$SAMPLES/building.jpg" \
  --meta '{"width_m": "large"}'
expect_fail "bad width_m metadata" "width_m" "$MVKP" recognize "$DB" "$T/view_a.png" --camera "$T/calib.yml"
expect_ok "bad width_m metadata does not matter without --camera" "$MVKP" recognize "$DB" "$T/view_a.png"

cli_finish
