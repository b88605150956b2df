#!/usr/bin/env python3
"""Relight the cast shadows of generated aerial scenes, to measure what
shadow compensation can give the registration (issue 21; docs/aerial.md,
"Shadow compensation: measured, opt-in"). Copies SRC (an aerial_eval.py
--out directory of one style) to DST with every photo.png relit; then run
aerial_eval.py on DST with the same arguments: it finds the scenes there and
registers them again.

  oracle:    the true shadow mask, from the same scenes rendered with the sun
             overhead (TWIN: aerial_eval.py --synth-args='--sun-elevation 90'
             with the same seed and style): pixels whose brightness rises by
             > 25 % without the shadows.
  prototype: the detector of src/mvkp/ortho/shadows.cc in numpy at the
             photo's full size, with the shadow step GIVEN (--step, log B G R;
             the default is synth-city's, as measured on seed 122) instead of
             found in the photo. An upper bound for that detector, not a
             method: the step is the generator's.

Either way the mask is relit by the step: (I + 6) * exp(-step * mask) - 6.

  scripts/shadow_relight.py oracle out/s122/suburb out/s122-relit/suburb --twin out/s122-nosun/suburb
  scripts/shadow_relight.py prototype out/s122/suburb out/s122-proto/suburb
"""
import argparse
import os
import shutil

import cv2
import numpy as np


def log_img(img):
    return np.log(cv2.GaussianBlur(img.astype(np.float32), (0, 0), 1.0) + 6)


def seeds(img, step, eps=0.05, radii=(3, 6, 10, 16), ndir=16):
    L = log_img(img)
    R = L - step
    hit = np.zeros(L.shape[:2], bool)
    for r in radii:
        for k in range(ndir):
            a = 2 * np.pi * k / ndir
            dx, dy = int(round(r * np.cos(a))), int(round(r * np.sin(a)))
            Q = np.roll(np.roll(L, dy, 0), dx, 1)
            hit |= np.abs(R - Q).max(2) < eps
    return cv2.morphologyEx(hit.astype(np.uint8), cv2.MORPH_OPEN, np.ones((2, 2), np.uint8)) > 0


def grow_creeping(img, seed, tol=0.05, k=5, iters=40):
    """The first growth: a 5 x 5 window, no brightness bound (it creeps up a
    penumbra's ramp into the lit ground)."""
    L = log_img(img)
    m = seed.astype(np.float32)
    for _ in range(iters):
        s = cv2.boxFilter(m, -1, (k, k), normalize=False)
        mean = np.stack([cv2.boxFilter(L[:, :, c] * m, -1, (k, k), normalize=False) for c in range(3)], 2)
        mean /= np.maximum(s, 1e-6)[:, :, None]
        new = np.maximum(m, ((s > 0) & (np.abs(L - mean).max(2) < tol)).astype(np.float32))
        if (new != m).sum() == 0:
            break
        m = new
    return m > 0


def grow(img, seed, tol=0.06, k=15, up=0.03, iters=60):
    L = log_img(img)
    Lm = L.mean(2)
    m = seed.astype(np.float32)
    for _ in range(iters):
        s = cv2.boxFilter(m, -1, (k, k), normalize=False)
        mean = np.stack([cv2.boxFilter(L[:, :, c] * m, -1, (k, k), normalize=False) for c in range(3)], 2)
        mean /= np.maximum(s, 1e-6)[:, :, None]
        near = cv2.dilate(m, np.ones((3, 3), np.uint8)) > 0
        cand = near & (s > 0) & (np.abs(L - mean).max(2) < tol) & (Lm <= mean.mean(2) + up)
        new = np.maximum(m, cand.astype(np.float32))
        if (new != m).sum() == 0:
            break
        m = new
    return m > 0


def relight(img, mask, step):
    w = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), 1.0)
    out = (img.astype(np.float32) + 6) * np.exp(-step[None, None, :] * w[:, :, None]) - 6
    return np.clip(out, 0, 255).astype(np.uint8)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["oracle", "prototype"])
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--twin", help="oracle: the same scenes without cast shadows")
    ap.add_argument("--step", default="-0.33,-0.44,-0.55", help="log B,G,R shadow step")
    ap.add_argument("--grow", choices=["anchored", "creeping", "none"], default="anchored",
                    help="prototype: the growth from the seeds (anchored: 15 x 15 window, as shadows.cc)")
    a = ap.parse_args()
    if a.mode == "oracle" and not a.twin:
        ap.error("oracle needs --twin")
    step = np.array([float(v) for v in a.step.split(",")], np.float32)
    if step.shape != (3,) or not (step < 0).all():
        ap.error("--step: three negative numbers")
    if os.path.exists(a.dst):
        shutil.rmtree(a.dst)
    shutil.copytree(a.src, a.dst, ignore=shutil.ignore_patterns("summary.json"))
    n = 0
    for root, _, files in os.walk(a.dst):
        if "photo.png" not in files:
            continue
        p = os.path.join(root, "photo.png")
        img = cv2.imread(p)
        if a.mode == "oracle":
            twin = cv2.imread(os.path.join(a.twin, os.path.relpath(p, a.dst)))
            if twin is None or twin.shape != img.shape:
                raise SystemExit("no twin photo of the same size for " + p)
            mask = ((twin.astype(np.float32) + 1) / (img.astype(np.float32) + 1)).mean(2) > 1.25
        else:
            sd = seeds(img, step)
            mask = grow(img, sd) if a.grow == "anchored" else grow_creeping(img, sd) if a.grow == "creeping" else sd
        cv2.imwrite(p, relight(img, mask, step))
        n += 1
    print("relit %d photos into %s" % (n, a.dst))


if __name__ == "__main__":
    main()
