#!/usr/bin/python3
"""make-gallery.py: synthetic "gallery" frames for multi-target recognition
(issue 6), with ground truth, plus frames that hold none of the targets.

  make-gallery.py --targets DIR_OR_LIST --backgrounds DIR --out OUT
                  [--scenes 150] [--no-target 200] [--seed 1]
                  [--max-target-side 640] [--width 640 --height 480]

--targets   a folder of images, a text file with one image path per line, or
            a CSV with a header holding 'image' (and optionally 'id', 'title';
            relative paths are relative to the list). Ids are the file stems
            (lower case, [a-z0-9_]) unless the CSV gives them.
--backgrounds  a folder of real photos (and optionally .avi/.mp4 videos)
            that are NOT targets and do not show any target: they give the
            cluttered backgrounds, the non-target pictures hung in frames, and
            the no-target frames.

Writes
  OUT/targets/ID.png     every target, downscaled (INTER_AREA) so its longest
                         side is at most --max-target-side (640 = the size
                         `mvkp db add` trains at, so mvkp and the SIFT baseline
                         see the same pixels); ground truth refers to these.
  OUT/targets.csv        id,image,title - the list for `mvkp db import`.
  OUT/scenes/scene_NNNN.jpg    gallery scenes: a background photo cropped and
                         rescaled, procedural clutter, a "wall", 1-3 framed
                         targets at random 3-D poses (tilt <= 35 deg, in-plane
                         rotation <= 20 deg, 25-60 % of the frame width, not
                         overlapping), then lighting (gain 0.6-1.4, gradient,
                         vignetting, colour cast), blur, Gaussian noise
                         sigma 2-6 and JPEG quality 75-95.
  OUT/notarget/none_NNNN.jpg   frames without any target: crops of real
                         photos, video frames, and walls with framed
                         NON-target pictures (same rendering chain).
  OUT/frames.txt         every frame, one path (relative to OUT) a line.
  OUT/ground_truth.json  {"targets": {id: {file, width, height}},
                          "frames": [{"file", "kind", "objects": [{"id",
                          "H" (3x3, target pixels -> frame pixels, pixel
                          centres), "corners" ((0,0),(w-1,0),(w-1,h-1),(0,h-1)
                          mapped), "width_frac", "tilt_deg", "roll_deg",
                          "scale", "area_frac"}]}]}
Deterministic: the same inputs and --seed give the same files.
Needs /usr/bin/python3 with numpy and cv2.
"""
import argparse
import csv
import json
import math
import os
import re
import sys

import cv2
import numpy as np

cv2.setNumThreads(1)
IMG_EXT = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
VID_EXT = (".avi", ".mp4", ".mkv")
WORDS = ("EXIT GALLERY ROOM TICKETS MUSEUM SHOP CAFE OPEN CLOSED NO FLASH PLEASE DO NOT TOUCH "
         "LEVEL 2 AUDIO GUIDE INFO TOILETS LIFT STAIRS OIL ON CANVAS 1889 LOAN COLLECTION").split()


def fail(msg):
    sys.exit("make-gallery: " + msg)


def sanitize(s):
    s = re.sub(r"[^a-z0-9_]+", "_", s.lower()).strip("_")
    return s or "target"


def read_targets(spec):
    """[(id, path, title)] from a folder, a path list or a CSV."""
    out = []
    if os.path.isdir(spec):
        for f in sorted(os.listdir(spec)):
            if f.lower().endswith(IMG_EXT):
                out.append((sanitize(os.path.splitext(f)[0]), os.path.join(spec, f), os.path.splitext(f)[0]))
    elif os.path.isfile(spec):
        base = os.path.dirname(os.path.abspath(spec))
        res = lambda p: p if os.path.isabs(p) else os.path.join(base, p)
        with open(spec, newline="") as fh:
            text = fh.read()
        first = text.splitlines()[0] if text.strip() else ""
        if "image" in [c.strip() for c in first.split(",")]:
            for row in csv.DictReader(text.splitlines()):
                p = res(row["image"].strip())
                stem = os.path.splitext(os.path.basename(p))[0]
                out.append((sanitize(row.get("id") or stem), p, row.get("title") or stem))
        else:
            for line in text.splitlines():
                line = line.split("#", 1)[0].strip()
                if line:
                    p = res(line)
                    stem = os.path.splitext(os.path.basename(p))[0]
                    out.append((sanitize(stem), p, stem))
    else:
        fail(f"--targets {spec}: no such folder or list")
    ids = [t[0] for t in out]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        fail("duplicate target ids: " + ", ".join(dup))
    if not out:
        fail(f"--targets {spec}: no images")
    return out


def load_bgr(path):
    im = cv2.imread(path, cv2.IMREAD_COLOR)
    if im is None:
        fail(f"cannot read {path}")
    return im


def cover(im, w, h):
    s = max(w / im.shape[1], h / im.shape[0])
    r = cv2.resize(im, (max(w, round(im.shape[1] * s)), max(h, round(im.shape[0] * s))),
                   interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_CUBIC)
    y, x = (r.shape[0] - h) // 2, (r.shape[1] - w) // 2
    return r[y:y + h, x:x + w].copy()


class Pool:
    """Non-target photos (and video frames) for backgrounds and decoys."""

    def __init__(self, folder):
        self.images, self.videos = [], []
        for f in sorted(os.listdir(folder)):
            p = os.path.join(folder, f)
            if f.lower().endswith(IMG_EXT):
                im = cv2.imread(p, cv2.IMREAD_COLOR)
                if im is not None and min(im.shape[:2]) >= 100:
                    self.images.append((f, im))
            elif f.lower().endswith(VID_EXT):
                cap = cv2.VideoCapture(p)
                n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
                cap.release()
                if n > 0:
                    self.videos.append((f, p, n))
        if len(self.images) < 3:
            fail(f"--backgrounds {folder}: need at least 3 readable photos")

    def photo(self, rng):
        name, im = self.images[rng.integers(len(self.images))]
        return name, im

    def crop(self, rng, w, h, min_area=0.25):
        """A random crop (area fraction min_area..1, random aspect jitter,
        random mirror) of a random photo, resized to w x h."""
        name, im = self.photo(rng)
        H, W = im.shape[:2]
        a = rng.uniform(min_area, 1.0)
        aspect = (w / h) * math.exp(rng.uniform(-0.2, 0.2))
        cw = min(W, int(math.sqrt(a * W * H * aspect)))
        ch = min(H, int(cw / aspect))
        cw = max(16, cw)
        ch = max(16, ch)
        x = int(rng.integers(0, max(1, W - cw + 1)))
        y = int(rng.integers(0, max(1, H - ch + 1)))
        c = im[y:y + ch, x:x + cw]
        if rng.random() < 0.5:
            c = c[:, ::-1]
        return name, cover(np.ascontiguousarray(c), w, h)

    def video_frame(self, rng, w, h):
        name, p, n = self.videos[rng.integers(len(self.videos))]
        k = int(rng.integers(n))
        cap = cv2.VideoCapture(p)
        cap.set(cv2.CAP_PROP_POS_FRAMES, k)
        ok, f = cap.read()
        cap.release()
        if not ok:
            return None, None
        return f"{name}#{k}", cover(f, w, h)


# ------------------------------------------------------------------ drawing
def clutter(img, rng, pool, n):
    """Procedural clutter: shapes, lines, text, pasted photo patches."""
    Hh, Ww = img.shape[:2]
    for _ in range(n):
        kind = rng.integers(5)
        col = tuple(int(c) for c in rng.integers(0, 256, 3))
        x, y = int(rng.integers(Ww)), int(rng.integers(Hh))
        if kind == 0:
            w, h = int(rng.integers(10, 120)), int(rng.integers(10, 120))
            cv2.rectangle(img, (x, y), (x + w, y + h), col, -1 if rng.random() < 0.6 else int(rng.integers(1, 5)))
        elif kind == 1:
            cv2.ellipse(img, (x, y), (int(rng.integers(5, 60)), int(rng.integers(5, 60))), float(rng.uniform(0, 180)),
                        0, 360, col, -1 if rng.random() < 0.5 else 2, cv2.LINE_AA)
        elif kind == 2:
            cv2.line(img, (x, y), (int(rng.integers(Ww)), int(rng.integers(Hh))), col, int(rng.integers(1, 6)),
                     cv2.LINE_AA)
        elif kind == 3:
            s = " ".join(rng.choice(WORDS, int(rng.integers(1, 4))))
            cv2.putText(img, s, (x - 40, y), int(rng.choice([0, 2, 3, 4])), float(rng.uniform(0.4, 1.4)), col,
                        int(rng.integers(1, 4)), cv2.LINE_AA)
        else:
            w, h = int(rng.integers(30, 160)), int(rng.integers(30, 160))
            _, patch = pool.crop(rng, w, h, 0.05)
            x, y = min(x, Ww - w), min(y, Hh - h)
            img[y:y + h, x:x + w] = patch


def wall(img, rng):
    """Paints a wall (plain colour, faint low-frequency texture) over most of
    the frame, in perspective, leaving some background above/below/aside.
    Returns the wall mask (bool)."""
    Hh, Ww = img.shape[:2]
    top_l, top_r = rng.uniform(-0.1, 0.25) * Hh, rng.uniform(-0.1, 0.25) * Hh
    bot_l, bot_r = rng.uniform(0.65, 1.1) * Hh, rng.uniform(0.65, 1.1) * Hh
    left = rng.uniform(-0.2, 0.12) * Ww if rng.random() < 0.5 else -10
    right = rng.uniform(0.88, 1.2) * Ww if rng.random() < 0.5 else Ww + 10
    poly = np.float32([[left, top_l], [right, top_r], [right, bot_r], [left, bot_l]])
    mask = np.zeros((Hh, Ww), np.uint8)
    cv2.fillConvexPoly(mask, np.int32(np.round(poly)), 255, cv2.LINE_AA)
    base = rng.uniform(120, 240) * np.float32(1 + rng.uniform(-0.12, 0.12, 3))
    tex = cv2.resize(rng.normal(0, 1, (12, 16)).astype(np.float32), (Ww, Hh), interpolation=cv2.INTER_CUBIC)
    fine = cv2.GaussianBlur(rng.normal(0, 1, (Hh, Ww)).astype(np.float32), (0, 0), 1.2)
    w = base[None, None, :] + (tex * rng.uniform(3, 12) + fine * rng.uniform(0, 4))[:, :, None]
    a = (mask.astype(np.float32) / 255)[:, :, None]
    img[:] = np.clip(img * (1 - a) + w * a, 0, 255)
    # a skirting board / rail line now and then
    if rng.random() < 0.5:
        y = int(min(bot_l, bot_r) - rng.uniform(5, 30))
        cv2.line(img, (0, y), (Ww, y + int(rng.integers(-8, 9))), tuple(float(c) for c in base * 0.7), 4, cv2.LINE_AA)
    return mask > 127


def framed(picture, rng):
    """The picture with a mat (sometimes) and a frame; returns (image, offset)
    where offset is the picture's top-left in the framed image."""
    h, w = picture.shape[:2]
    m = max(h, w)
    mat = int(round(rng.uniform(0.03, 0.07) * m)) if rng.random() < 0.3 else 0
    fw = max(3, int(round(rng.uniform(0.025, 0.07) * m)))
    styles = [(30, 55, 90), (40, 140, 190), (25, 25, 25), (230, 230, 230), (60, 80, 110), (200, 200, 205)]
    col = np.float32(styles[rng.integers(len(styles))]) * np.float32(rng.uniform(0.85, 1.15))
    b = mat + fw
    out = np.empty((h + 2 * b, w + 2 * b, 3), np.float32)
    out[:] = np.clip(col, 0, 255)
    # wood-ish grain / bevel on the frame
    grain = rng.normal(0, rng.uniform(2, 10), out.shape[:2]).astype(np.float32)
    grain = cv2.GaussianBlur(grain, (0, 0), 0.8)
    out += grain[:, :, None]
    H2, W2 = out.shape[:2]
    cv2.rectangle(out, (0, 0), (W2 - 1, H2 - 1), tuple(float(c) for c in np.clip(col * 1.35, 0, 255)), max(1, fw // 4))
    cv2.rectangle(out, (fw - 2, fw - 2), (W2 - fw + 1, H2 - fw + 1), tuple(float(c) for c in col * 0.55),
                  max(1, fw // 5))
    if mat:
        out[fw:H2 - fw, fw:W2 - fw] = np.float32(rng.uniform(215, 245)) + rng.normal(0, 1.5, (H2 - 2 * fw, W2 - 2 * fw, 1))
    out[b:b + h, b:b + w] = picture
    return np.clip(out, 0, 255).astype(np.uint8), b


def pose_angles(rng):
    """(tilt <= 35 deg about a random in-plane axis, that axis, roll <= 20 deg), radians."""
    return (math.radians(rng.uniform(0, 35)), rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(-20, 20)))


def pose_homography(w, h, angles, Ww, Hh, width_frac, center, f):
    """Homography target pixels -> frame for a planar target of w x h pixels
    seen by a pinhole camera (focal f) tilted by up to 35 deg about a random
    in-plane axis, rolled by up to 20 deg, centred at `center`, its outline
    about width_frac * Ww wide. Returns (H, tilt_deg, roll_deg)."""
    tilt, phi, roll = angles
    ax = np.array([math.cos(phi), math.sin(phi), 0.0])
    R_t, _ = cv2.Rodrigues(ax * tilt)
    R_r = np.array([[math.cos(roll), -math.sin(roll), 0], [math.sin(roll), math.cos(roll), 0], [0, 0, 1]])
    R = R_r @ R_t
    src = np.float64([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]])

    def project(size):
        k = size / w  # world units per target pixel (at depth f: 1 unit = 1 frame pixel)
        P = np.c_[(src - [(w - 1) / 2, (h - 1) / 2]) * k, np.zeros(4)]
        ray = np.array([(center[0] - (Ww - 1) / 2) / f, (center[1] - (Hh - 1) / 2) / f, 1.0]) * f
        X = P @ R.T + ray
        return np.c_[f * X[:, 0] / X[:, 2] + (Ww - 1) / 2, f * X[:, 1] / X[:, 2] + (Hh - 1) / 2]

    want = width_frac * Ww
    size = want
    for _ in range(3):  # the tilt changes the outline's width; rescale
        dst = project(size)
        size *= want / max(1e-6, dst[:, 0].max() - dst[:, 0].min())
    dst = project(size)
    H = cv2.getPerspectiveTransform(np.float32(src), np.float32(dst)).astype(np.float64)
    return H, math.degrees(tilt), math.degrees(roll)


def apply_h(H, pts):
    p = np.c_[np.asarray(pts, np.float64), np.ones(len(pts))] @ H.T
    return p[:, :2] / p[:, 2:3]


def paste(canvas, pic_framed, H_framed, rng, shadow=True):
    """Warps the framed picture into the float canvas with anti-aliasing (the
    picture is first shrunk near the local scale) and a soft drop shadow."""
    Hh, Ww = canvas.shape[:2]
    fh, fw = pic_framed.shape[:2]
    c = apply_h(H_framed, [[(fw - 1) / 2, (fh - 1) / 2]])[0]
    J = H_framed[:2, :2] - np.outer(apply_h(H_framed, [[(fw - 1) / 2, (fh - 1) / 2]])[0], H_framed[2, :2])
    J /= (H_framed[2] @ [(fw - 1) / 2, (fh - 1) / 2, 1])
    scale = math.sqrt(abs(np.linalg.det(J)))
    src = pic_framed
    Hs = H_framed
    if scale < 0.9:
        ds = max(scale * 1.1, 0.05)
        nw, nh = max(2, round(fw * ds)), max(2, round(fh * ds))
        src = cv2.resize(pic_framed, (nw, nh), interpolation=cv2.INTER_AREA)
        # small pixel (x,y) centre <-> big ((x+0.5)*fw/nw - 0.5, ...)
        S = np.array([[fw / nw, 0, 0.5 * fw / nw - 0.5], [0, fh / nh, 0.5 * fh / nh - 0.5], [0, 0, 1]])
        Hs = H_framed @ S
    sh, sw = src.shape[:2]
    warped = cv2.warpPerspective(src.astype(np.float32), Hs, (Ww, Hh), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_CONSTANT)
    ones = np.ones((sh, sw), np.float32)
    a = cv2.warpPerspective(ones, Hs, (Ww, Hh), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    if shadow:
        d = rng.uniform(2, 8)
        T = np.array([[1, 0, d * rng.uniform(0.3, 1)], [0, 1, d], [0, 0, 1]])
        s = cv2.warpPerspective(ones, T @ Hs, (Ww, Hh), flags=cv2.INTER_LINEAR)
        s = cv2.GaussianBlur(s, (0, 0), rng.uniform(2, 5)) * rng.uniform(0.25, 0.5)
        canvas *= (1 - s)[:, :, None]
    canvas[:] = canvas * (1 - a[:, :, None]) + warped * a[:, :, None]
    return c, scale


def finish(img, rng):
    """Lighting, blur, noise; returns uint8 BGR and the parameters used."""
    Hh, Ww = img.shape[:2]
    gain = rng.uniform(0.6, 1.4)
    yy, xx = np.mgrid[0:Hh, 0:Ww].astype(np.float32)
    ang = rng.uniform(0, 2 * math.pi)
    g_amp = rng.uniform(0, 0.35)
    proj = ((xx - Ww / 2) * math.cos(ang) + (yy - Hh / 2) * math.sin(ang)) / (0.5 * math.hypot(Ww, Hh))
    vig = rng.uniform(0, 0.5)
    r2 = ((xx - Ww / 2) ** 2 + (yy - Hh / 2) ** 2) / ((Ww / 2) ** 2 + (Hh / 2) ** 2)
    light = gain * (1 + g_amp * proj) * (1 - vig * r2)
    cast = np.float32(1 + rng.uniform(-0.08, 0.08, 3))
    out = img * light[:, :, None] * cast[None, None, :]
    blur = rng.uniform(0.3, 1.2)
    out = cv2.GaussianBlur(out, (0, 0), blur)
    noise = rng.uniform(2, 6)
    out = out + rng.normal(0, noise, out.shape).astype(np.float32)
    q = int(rng.integers(75, 96))
    return np.clip(out + 0.5, 0, 255).astype(np.uint8), {
        "gain": round(gain, 3), "gradient": round(g_amp, 3), "vignette": round(vig, 3), "blur_sigma": round(blur, 3),
        "noise_sigma": round(noise, 3), "jpeg_quality": q}


def place(pictures, rng, Ww, Hh, wall_mask, f):
    """Poses for the pictures (list of (image, id)): non-overlapping framed
    outlines inside the frame. Returns [(pic, id, H, H_framed, b, framed, tilt, roll, frac)]."""
    occupied = np.zeros((Hh, Ww), np.uint8)
    placed = []
    n = len(pictures)
    hi = {1: 0.60, 2: 0.50, 3: 0.40}[n]
    for pic, pid in pictures:
        h, w = pic.shape[:2]
        fr, b = framed(pic, rng)
        fh, fw = fr.shape[:2]
        T = np.array([[1, 0, -b], [0, 1, -b], [0, 0, 1]], np.float64)
        fcorn = [[-0.5, -0.5], [fw - 0.5, -0.5], [fw - 0.5, fh - 0.5], [-0.5, fh - 0.5]]
        # size first (uniform in 25 % .. hi, capped so the framed picture fits
        # vertically), then many positions; shrink only when nothing fits
        frac = rng.uniform(0.25, hi)
        frac = max(0.2, min(frac, 0.85 * Hh / Ww * (w / h)))
        ok = False
        for attempt in range(120):
            if attempt and attempt % 30 == 0:
                frac = max(0.2, frac * 0.9)
            # where can the centre go?  the extent of the outline at the frame centre
            angles = pose_angles(rng)
            H0, _, _ = pose_homography(w, h, angles, Ww, Hh, frac, ((Ww - 1) / 2, (Hh - 1) / 2), f)
            e = apply_h(H0 @ T, fcorn) - [(Ww - 1) / 2, (Hh - 1) / 2]
            lo_x, hi_x = 4 - e[:, 0].min(), Ww - 5 - e[:, 0].max()
            lo_y, hi_y = 4 - e[:, 1].min(), Hh - 5 - e[:, 1].max()
            if lo_x > hi_x or lo_y > hi_y:
                frac = max(0.2, frac * 0.95)
                continue
            center = (rng.uniform(lo_x, hi_x), rng.uniform(lo_y, hi_y))
            H, tilt, roll = pose_homography(w, h, angles, Ww, Hh, frac, center, f)
            Hf = H @ T
            fc = apply_h(Hf, fcorn)
            if fc[:, 0].min() < 3 or fc[:, 1].min() < 3 or fc[:, 0].max() > Ww - 4 or fc[:, 1].max() > Hh - 4:
                continue
            m = np.zeros((Hh, Ww), np.uint8)
            cv2.fillConvexPoly(m, np.int32(np.round(fc)), 1)
            m = cv2.dilate(m, np.ones((9, 9), np.uint8))
            if (m & occupied).any():
                continue
            occupied |= m
            placed.append((pic, pid, H, Hf, b, fr, tilt, roll))
            ok = True
            break
        if not ok:
            continue  # no room: fewer pictures in this scene
    return placed


def gallery_scene(rng, pool, pictures, Ww, Hh, labels=True):
    f = (Ww / 2) / math.tan(math.radians(rng.uniform(25, 35)))  # 50-70 deg horizontal field of view
    bg_name, bg = pool.crop(rng, Ww, Hh)
    img = bg.astype(np.float32)
    clutter(img, rng, pool, int(rng.integers(6, 20)))
    wm = wall(img, rng)
    placed = place(pictures, rng, Ww, Hh, wm, f)
    objects = []
    for pic, pid, H, Hf, b, fr, tilt, roll in placed:
        c, scale = paste(img, fr, Hf, rng)
        if labels and rng.random() < 0.6:  # a small caption card beside the picture
            h, w = pic.shape[:2]
            corners = apply_h(Hf, [[fr.shape[1] + 8, fr.shape[0] * 0.7]])[0]
            x, y = int(corners[0]), int(corners[1])
            if 0 <= x < Ww - 60 and 0 <= y < Hh - 30:
                cv2.rectangle(img, (x, y), (x + 56, y + 26), (238, 238, 238), -1)
                cv2.putText(img, " ".join(rng.choice(WORDS, 2)), (x + 3, y + 11), 0, 0.28, (40, 40, 40), 1, cv2.LINE_AA)
                cv2.putText(img, " ".join(rng.choice(WORDS, 2)), (x + 3, y + 21), 0, 0.25, (60, 60, 60), 1, cv2.LINE_AA)
        if pid is not None:
            h, w = pic.shape[:2]
            corners = apply_h(H, [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]])
            area = abs(cv2.contourArea(np.float32(corners)))
            objects.append({"id": pid, "H": [[round(v, 9) for v in r] for r in H.tolist()],
                            "corners": [[round(x, 3), round(y, 3)] for x, y in corners.tolist()],
                            "width_frac": round(float(corners[:, 0].max() - corners[:, 0].min()) / Ww, 4),
                            "tilt_deg": round(tilt, 2), "roll_deg": round(roll, 2), "scale": round(scale, 4),
                            "area_frac": round(area / (Ww * Hh), 4)})
    out, light = finish(img, rng)
    return out, objects, {"background": bg_name, "focal_px": round(f, 1), **light}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--targets", required=True)
    ap.add_argument("--backgrounds", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--scenes", type=int, default=150)
    ap.add_argument("--no-target", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--max-target-side", type=int, default=640)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    a = ap.parse_args()
    Ww, Hh = a.width, a.height

    targets = read_targets(a.targets)
    pool = Pool(a.backgrounds)
    os.makedirs(os.path.join(a.out, "targets"), exist_ok=True)
    os.makedirs(os.path.join(a.out, "scenes"), exist_ok=True)
    os.makedirs(os.path.join(a.out, "notarget"), exist_ok=True)
    timgs, tinfo = {}, {}
    with open(os.path.join(a.out, "targets.csv"), "w", newline="") as fh:
        wr = csv.writer(fh, lineterminator="\n")
        wr.writerow(["id", "image", "title"])
        for tid, path, title in targets:
            im = load_bgr(path)
            m = max(im.shape[:2])
            if m > a.max_target_side:
                s = a.max_target_side / m
                im = cv2.resize(im, (round(im.shape[1] * s), round(im.shape[0] * s)), interpolation=cv2.INTER_AREA)
            rel = f"targets/{tid}.png"
            cv2.imwrite(os.path.join(a.out, rel), im)
            timgs[tid] = im
            tinfo[tid] = {"file": rel, "width": im.shape[1], "height": im.shape[0], "source": path, "title": title}
            wr.writerow([tid, rel, title])

    ids = sorted(timgs)
    frames = []
    # Gallery scenes: targets dealt from reshuffled decks so every target
    # appears about equally often.
    deck = []
    deck_rng = np.random.default_rng([a.seed, 0])
    for i in range(a.scenes):
        rng = np.random.default_rng([a.seed, 1, i])
        k = int(rng.choice([1, 2, 3], p=[0.3, 0.4, 0.3]))
        chosen = []
        while len(chosen) < k:
            if not deck:
                deck = list(deck_rng.permutation(ids))
            t = deck.pop()
            if t in chosen:
                deck.insert(0, t)
                if len(set(deck) - set(chosen)) == 0:
                    break
                continue
            chosen.append(t)
        img, objs, info = gallery_scene(rng, pool, [(timgs[t], t) for t in chosen], Ww, Hh)
        rel = f"scenes/scene_{i:04d}.jpg"
        cv2.imwrite(os.path.join(a.out, rel), img, [cv2.IMWRITE_JPEG_QUALITY, info["jpeg_quality"]])
        frames.append({"file": rel, "kind": "gallery", "objects": objs, "render": info})

    # No-target frames: photo crops, video frames, walls with non-target pictures.
    for i in range(a.no_target):
        rng = np.random.default_rng([a.seed, 2, i])
        r = rng.random()
        kind = "photo" if r < 0.4 else ("video" if r < 0.6 and pool.videos else "decoy_gallery")
        info = {}
        if kind == "photo":
            name, im = pool.crop(rng, int(Ww * 1.3), int(Hh * 1.3), 0.1)
            # a hand-held look: small rotation + perspective, then the rendering chain
            ang, s = rng.uniform(-15, 15), rng.uniform(1.0, 1.2)
            M = cv2.getRotationMatrix2D((im.shape[1] / 2, im.shape[0] / 2), ang, s)
            im = cv2.warpAffine(im, M, (im.shape[1], im.shape[0]), borderMode=cv2.BORDER_REFLECT)
            y0, x0 = (im.shape[0] - Hh) // 2, (im.shape[1] - Ww) // 2
            img, info = finish(im[y0:y0 + Hh, x0:x0 + Ww].astype(np.float32), rng)
            info["source"] = name
        elif kind == "video":
            name, im = pool.video_frame(rng, Ww, Hh)
            if im is None:
                name, im = pool.crop(rng, Ww, Hh)
            img, info = finish(im.astype(np.float32), rng)
            info["source"] = name
        else:
            n = int(rng.choice([1, 2, 3], p=[0.3, 0.4, 0.3]))
            pics = []
            for _ in range(n):
                pw, ph = int(rng.integers(300, 640)), int(rng.integers(240, 560))
                name, p = pool.crop(rng, pw, ph, 0.15)
                pics.append((p, None))
            img, _, info = gallery_scene(rng, pool, pics, Ww, Hh)
        rel = f"notarget/none_{i:04d}.jpg"
        cv2.imwrite(os.path.join(a.out, rel), img, [cv2.IMWRITE_JPEG_QUALITY, info["jpeg_quality"]])
        frames.append({"file": rel, "kind": "notarget_" + kind, "objects": [], "render": info})

    with open(os.path.join(a.out, "frames.txt"), "w") as fh:
        fh.write("".join(f["file"] + "\n" for f in frames))
    gt = {"generator": "scripts/make-gallery.py", "seed": a.seed, "width": Ww, "height": Hh,
          "corner_convention": "(0,0),(w-1,0),(w-1,h-1),(0,h-1) of the target image, pixel centres",
          "targets": tinfo, "backgrounds": [n for n, _ in pool.images] + [n for n, _, _ in pool.videos],
          "frames": frames}
    with open(os.path.join(a.out, "ground_truth.json"), "w") as fh:
        json.dump(gt, fh, indent=1)
    n_obj = sum(len(f["objects"]) for f in frames)
    print(f"make-gallery: {len(ids)} targets, {a.scenes} gallery scenes with {n_obj} target instances, "
          f"{a.no_target} no-target frames in {a.out}")


if __name__ == "__main__":
    main()
