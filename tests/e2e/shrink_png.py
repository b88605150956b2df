#!/usr/bin/env python3
"""Makes the documentation's screenshots small: each PNG given is rewritten
with its colours rounded to steps of 16 (invisible on camera frames, which
are noise to PNG otherwise) and the strongest compression (~1/3 the size).

Usage: shrink_png.py FILE.png ...
"""
import sys

import cv2
import numpy as np

for path in sys.argv[1:]:
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        sys.exit("cannot read " + path)
    img = (np.round(img.astype(np.float32) / 16) * 16).clip(0, 255).astype(np.uint8)
    if not cv2.imwrite(path, img, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        sys.exit("cannot write " + path)
