#!/usr/bin/python3
"""quality_edit.py IN EDIT OUT: global photometric or size edits of an image.
EDIT is gainG (multiply), gammaG (255*(v/255)^G), bright+B / bright-B (offset)
or resizeF (area/cubic interpolation)."""
import sys

import cv2
import numpy as np

src, edit, dst = sys.argv[1:4]
img = cv2.imread(src, cv2.IMREAD_UNCHANGED)
if img is None:
    sys.exit(f"{src}: cannot read")
f = img.astype(np.float64)
if edit.startswith("gain"):
    f = f * float(edit[4:])
elif edit.startswith("gamma"):
    f = 255.0 * (f / 255.0) ** float(edit[5:])
elif edit.startswith("bright"):
    f = f + float(edit[6:])
elif edit.startswith("resize"):
    s = float(edit[6:])
    h, w = img.shape[:2]
    f = cv2.resize(img, (max(1, round(w * s)), max(1, round(h * s))),
                   interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_CUBIC).astype(np.float64)
else:
    sys.exit(f"unknown edit {edit}")
cv2.imwrite(dst, np.clip(np.rint(f), 0, 255).astype(np.uint8))
