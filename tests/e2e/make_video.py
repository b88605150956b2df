#!/usr/bin/env python3
"""Fake camera input for the web client's browser test (tests/e2e/browser_test.mjs).

Writes into OUTDIR:
  scene.y4m   640x480, 15 fps, 3 s, 4:2:0: samples/starry_night.jpg perspective-warped
              onto a background made from samples/fruits.jpg, with a slight hand
              shake (+-2 px) and sensor noise, for Chromium's
              --use-file-for-fake-video-capture
  empty.y4m   the same background without any exhibit (1 s)
  photo.jpg   1600x1200 photo of the painting on a coffee background (upload fallback;
              larger than the client's 640 px frames so that downscaling is exercised)
  building.jpg 1200x900 photo of samples/building.jpg on the same background (an exhibit
              without a link)
  scene.json  {"width", "height", "quad"}: the painting's corners in scene.y4m frames
              (top-left, top-right, bottom-right, bottom-left), without the shake
  scene4.y4m  640x480, 15 fps, 4 s: four paintings at once (starry_night, coffee,
              building, astronaut; issue 20) on the fruits wall, with the same shake
  scene4.json {"width", "height", "quads": {sample name: corners}}, without the shake

Usage: make_video.py SAMPLES OUTDIR
"""
import json
import os
import sys

import cv2
import numpy as np

W, H, FPS = 640, 480, 15
# The painting's corners in the video: a slightly turned frame, ~40% of the width.
QUAD = [(205.0, 118.0), (448.0, 132.0), (441.0, 352.0), (198.0, 366.0)]
# Four paintings in one frame (scene4.y4m), by sample name.
QUADS4 = {
    "starry_night": [(22.0, 18.0), (298.0, 26.0), (294.0, 240.0), (18.0, 244.0)],
    "coffee": [(338.0, 30.0), (620.0, 22.0), (622.0, 212.0), (342.0, 216.0)],
    "building": [(24.0, 266.0), (296.0, 262.0), (300.0, 450.0), (20.0, 454.0)],
    "astronaut": [(360.0, 258.0), (590.0, 264.0), (586.0, 466.0), (364.0, 462.0)],
}


def background(samples, name, w, h):
    img = cv2.imread(os.path.join(samples, name), cv2.IMREAD_COLOR)
    if img is None:
        sys.exit("cannot read " + name)
    # Cover w x h (crop the excess), then darken it a little, like a wall around a lit painting.
    s = max(w / img.shape[1], h / img.shape[0])
    img = cv2.resize(img, (int(np.ceil(img.shape[1] * s)), int(np.ceil(img.shape[0] * s))), interpolation=cv2.INTER_CUBIC)
    y0, x0 = (img.shape[0] - h) // 2, (img.shape[1] - w) // 2
    img = img[y0:y0 + h, x0:x0 + w]
    return cv2.GaussianBlur(img, (0, 0), 1.5).astype(np.float32) * 0.7


def paste(bg, painting, quad):
    h, w = painting.shape[:2]
    src = np.float32([(0, 0), (w - 1, 0), (w - 1, h - 1), (0, h - 1)])
    hom = cv2.getPerspectiveTransform(src, np.float32(quad))
    size = (bg.shape[1], bg.shape[0])
    warped = cv2.warpPerspective(painting, hom, size, flags=cv2.INTER_LINEAR).astype(np.float32)
    mask = cv2.warpPerspective(np.ones((h, w), np.float32), hom, size, flags=cv2.INTER_LINEAR)[..., None]
    return bg * (1 - mask) + warped * mask


def noisy(img, rng):
    return np.clip(img + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)


def write_y4m(path, frames):
    with open(path, "wb") as f:
        f.write(b"YUV4MPEG2 W%d H%d F%d:1 Ip A1:1 C420jpeg\n" % (W, H, FPS))
        for bgr in frames:
            f.write(b"FRAME\n")
            f.write(cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV_I420).tobytes())  # Y, then U, then V planes


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    samples, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(7)
    painting = cv2.imread(os.path.join(samples, "starry_night.jpg"), cv2.IMREAD_COLOR)
    building = cv2.imread(os.path.join(samples, "building.jpg"), cv2.IMREAD_COLOR)
    if painting is None or building is None:
        sys.exit("cannot read the samples in " + samples)

    bg = background(samples, "fruits.jpg", W, H)
    frames = []
    for i in range(3 * FPS):
        t = 2 * np.pi * i / (3 * FPS)
        dx, dy = 2.0 * np.sin(t), 1.5 * np.sin(2 * t)
        frames.append(noisy(paste(bg, painting, [(x + dx, y + dy) for x, y in QUAD]), rng))
    write_y4m(os.path.join(out, "scene.y4m"), frames)
    write_y4m(os.path.join(out, "empty.y4m"), [noisy(bg, rng) for _ in range(FPS)])

    # Photos for the upload fallback: the same layout, scaled up, on another wall.
    for name, img, (pw, ph) in (("photo.jpg", painting, (1600, 1200)), ("building.jpg", building, (1200, 900))):
        s = pw / W
        photo = paste(background(samples, "coffee.jpg", pw, ph), img, [(x * s, y * s) for x, y in QUAD])
        cv2.imwrite(os.path.join(out, name), noisy(photo, rng), [cv2.IMWRITE_JPEG_QUALITY, 90])

    with open(os.path.join(out, "scene.json"), "w") as f:
        json.dump({"width": W, "height": H, "quad": QUAD}, f)

    # Four paintings at once, each about 40 % of the frame's width, slightly turned.
    pictures = {name: cv2.imread(os.path.join(samples, name + ".jpg"), cv2.IMREAD_COLOR) for name in QUADS4}
    if any(p is None for p in pictures.values()):
        sys.exit("cannot read the samples in " + samples)
    frames = []
    for i in range(4 * FPS):
        t = 2 * np.pi * i / (4 * FPS)
        dx, dy = 2.0 * np.sin(t), 1.5 * np.sin(2 * t)
        img = bg
        for name, quad in QUADS4.items():
            img = paste(img, pictures[name], [(x + dx, y + dy) for x, y in quad])
        frames.append(noisy(img, rng))
    write_y4m(os.path.join(out, "scene4.y4m"), frames)
    with open(os.path.join(out, "scene4.json"), "w") as f:
        json.dump({"width": W, "height": H, "quads": QUADS4}, f)


if __name__ == "__main__":
    main()
