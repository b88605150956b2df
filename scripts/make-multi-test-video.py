#!/usr/bin/python3
"""make-multi-test-video.py BACKGROUND OUT.avi FRAMES ID=IMAGE[@LAST] ...: a 640x480
MJPG video of several targets at once (issue 20), each moving smoothly on its own
path (scale, rotation, tilt; its own part of one path, no jumps) over BACKGROUND, with mild noise, for `mvkp video`
tests. Each target is shown 200 px on its longest side in one of three places
(top left, top right, bottom middle; at most three targets); @LAST: the last frame
it is in view (then it is gone). Writes OUT.avi and OUT.avi.truth.json: per frame,
{id: homography (3x3, row-major) from the target image's own pixels (as stored in
a database) to frame pixels}, only for the targets in view."""
import json
import math
import sys

import cv2
import numpy as np

if len(sys.argv) < 5:
    sys.exit(__doc__)
bg_path, out, frames = sys.argv[1], sys.argv[2], int(sys.argv[3])
CENTRES = [(150, 125), (480, 135), (320, 365)]
specs = sys.argv[4:]
if len(specs) > len(CENTRES):
    sys.exit("at most %d targets" % len(CENTRES))
bg = cv2.imread(bg_path)
if bg is None:
    sys.exit("cannot read " + bg_path)
bg = cv2.resize(bg, (640, 480))
targets = []
for k, spec in enumerate(specs):
    tid, rest = spec.split("=", 1)
    path, last = (rest.rsplit("@", 1) + [None])[:2] if "@" in rest else (rest, None)
    img = cv2.imread(path)
    if img is None:
        sys.exit("cannot read " + path)
    s = 200.0 / max(img.shape[:2])
    small = cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
    targets.append({"id": tid, "img": small, "s": s, "centre": CENTRES[k],
                    "last": int(last) if last is not None else frames - 1, "phase": 0.15 * k})


def path_h(w, h, t, centre):
    ang = math.radians(-15 + 30 * t)
    sc = 0.85 + 0.25 * math.sin(math.pi * t)
    tilt = 0.12 * math.sin(2 * math.pi * t)
    cx, cy = centre[0] + 40 * math.sin(2 * math.pi * t), centre[1] + 25 * math.cos(2 * math.pi * t)
    src = np.float32([[0, 0], [w, 0], [w, h], [0, h]]) - np.float32([w / 2, h / 2])
    R = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    dst = (src @ R.T) * sc
    dst[:, 0] *= 1 + tilt * (src[:, 1] / h)
    dst += np.float32([cx, cy])
    return cv2.getPerspectiveTransform(np.float32([[0, 0], [w, 0], [w, h], [0, h]]), np.float32(dst))


rng = np.random.default_rng(11)
vw = cv2.VideoWriter(out, cv2.VideoWriter_fourcc(*"MJPG"), 25, (640, 480))
if not vw.isOpened():
    sys.exit("cannot open the video writer")
truth = []
for i in range(frames):
    frame = bg.copy()
    seen = {}
    for t in targets:
        if i > t["last"]:
            continue
        h, w = t["img"].shape[:2]
        H = path_h(w, h, t["phase"] + 0.7 * i / max(1, frames - 1), t["centre"])
        warped = cv2.warpPerspective(t["img"], H, (640, 480))
        mask = cv2.warpPerspective(np.full((h, w), 255, np.uint8), H, (640, 480))
        frame[mask > 0] = warped[mask > 0]
        # Stored image pixels -> shown image pixels -> frame pixels.
        S = np.diag([t["s"], t["s"], 1.0])
        seen[t["id"]] = (H @ S).ravel().tolist()
    truth.append(seen)
    vw.write(np.clip(frame.astype(np.float32) + rng.normal(0, 3, frame.shape), 0, 255).astype(np.uint8))
vw.release()
with open(out + ".truth.json", "w") as f:
    json.dump(truth, f)
