#!/usr/bin/env python3
"""Site files and photos for the visitor-page checks of browser_test.mjs.

Usage: make_site.py SAMPLES OUT
Writes into OUT:
  logo.png   a 96x96 PNG logo
  site.json  the museum's name, intro, colours and logo (mvkp serve --site)
  two.jpg    1600x1200 photo of two exhibits side by side (starry_night.jpg, building.jpg)
  portrait.y4m, portrait.json  a 450x800 camera (a phone held upright delivers
             upright 9:16 frames) seeing the painting, and its corners {"width", "height", "quad"}
"""
import json
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_video import background, noisy, paste  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    samples, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    logo = np.full((96, 96, 3), (32, 24, 122), np.uint8)  # BGR: deep red
    cv2.circle(logo, (48, 48), 30, (77, 204, 255), -1)
    cv2.rectangle(logo, (30, 44), (66, 52), (32, 24, 122), -1)
    cv2.imwrite(os.path.join(out, "logo.png"), logo)
    with open(os.path.join(out, "site.json"), "w", encoding="utf-8") as f:
        json.dump({"name": "Musée de l'Exemple",
                   "intro": "Point your phone at a painting to read about it, or browse the exhibits.",
                   "logo": "logo.png",
                   "colors": {"background": "#7a1820", "text": "#ffffff", "accent": "#ffcc4d"}}, f, ensure_ascii=False)
    rng = np.random.default_rng(11)
    photo = background(samples, "coffee.jpg", 1600, 1200)
    for name, quad in (("starry_night.jpg", [(120, 330), (760, 350), (750, 850), (110, 870)]),
                       ("building.jpg", [(880, 300), (1500, 320), (1490, 800), (870, 820)])):
        img = cv2.imread(os.path.join(samples, name), cv2.IMREAD_COLOR)
        if img is None:
            sys.exit("cannot read " + name)
        photo = paste(photo, img, quad)
    cv2.imwrite(os.path.join(out, "two.jpg"), noisy(photo, rng), [cv2.IMWRITE_JPEG_QUALITY, 90])

    w, h, fps = 450, 800, 15
    quad = [(78.0, 290.0), (372.0, 305.0), (366.0, 515.0), (72.0, 530.0)]
    painting = cv2.imread(os.path.join(samples, "starry_night.jpg"), cv2.IMREAD_COLOR)
    wall = background(samples, "fruits.jpg", w, h)
    with open(os.path.join(out, "portrait.y4m"), "wb") as f:
        f.write(b"YUV4MPEG2 W%d H%d F%d:1 Ip A1:1 C420jpeg\n" % (w, h, fps))
        for i in range(2 * fps):
            t = 2 * np.pi * i / (2 * fps)
            frame = noisy(paste(wall, painting, [(x + 1.5 * np.sin(t), y + np.sin(2 * t)) for x, y in quad]), rng)
            f.write(b"FRAME\n")
            f.write(cv2.cvtColor(frame, cv2.COLOR_BGR2YUV_I420).tobytes())
    with open(os.path.join(out, "portrait.json"), "w") as f:
        json.dump({"width": w, "height": h, "quad": quad}, f)


if __name__ == "__main__":
    main()
