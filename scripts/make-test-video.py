#!/usr/bin/python3
"""make-test-video.py TARGET BACKGROUND OUT.avi [FRAMES] [--gone N]: a 640x480
MJPG video of TARGET moving smoothly (scale, rotation, tilt) over BACKGROUND,
with mild noise, for `mvkp video` tests. The last N frames (--gone) show the
background only. Writes OUT.avi and OUT.avi.H.txt (one 3x3 homography per
frame, target pixels -> frame pixels, 'none' where the target is gone)."""
import math
import sys

import cv2
import numpy as np

args = [a for a in sys.argv[1:] if not a.startswith("--")]
gone = 0
if "--gone" in sys.argv:
    gone = int(sys.argv[sys.argv.index("--gone") + 1])
    args = [a for a in args if a != str(gone)]
target_path, bg_path, out = args[:3]
frames = int(args[3]) if len(args) > 3 else 60
tgt = cv2.imread(target_path)
bg = cv2.imread(bg_path)
if tgt is None or bg is None:
    sys.exit("cannot read the target or the background")
s = 300.0 / max(tgt.shape[:2])
tgt = cv2.resize(tgt, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
bg = cv2.resize(bg, (640, 480))
h, w = tgt.shape[:2]
rng = np.random.default_rng(7)
vw = cv2.VideoWriter(out, cv2.VideoWriter_fourcc(*"MJPG"), 25, (640, 480))
if not vw.isOpened():
    sys.exit("cannot open the video writer")
hs = []
for i in range(frames + gone):
    frame = bg.copy()
    if i < frames:
        t = i / max(1, frames - 1)
        ang = math.radians(-20 + 40 * t)
        sc = 0.9 + 0.4 * math.sin(math.pi * t)
        tilt = 0.15 * math.sin(2 * math.pi * t)
        cx, cy = 320 + 60 * math.sin(2 * math.pi * t), 240 + 30 * math.cos(2 * math.pi * t)
        src = np.float32([[0, 0], [w, 0], [w, h], [0, h]]) - np.float32([w / 2, h / 2])
        R = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
        dst = (src @ R.T) * sc
        dst[:, 0] *= 1 + tilt * (src[:, 1] / h)
        dst += np.float32([cx, cy])
        H = cv2.getPerspectiveTransform(np.float32([[0, 0], [w, 0], [w, h], [0, h]]), np.float32(dst))
        warped = cv2.warpPerspective(tgt, H, (640, 480))
        mask = cv2.warpPerspective(np.full((h, w), 255, np.uint8), H, (640, 480))
        frame[mask > 0] = warped[mask > 0]
        hs.append(" ".join("%.9g" % v for v in H.ravel()))
    else:
        hs.append("none")
    noisy = np.clip(frame.astype(np.float32) + rng.normal(0, 3, frame.shape), 0, 255).astype(np.uint8)
    vw.write(noisy)
vw.release()
open(out + ".H.txt", "w").write("\n".join(hs) + "\n")
