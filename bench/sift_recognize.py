#!/usr/bin/python3
"""sift_recognize.py: multi-target OpenCV SIFT + RANSAC recogniser, the
baseline for `mvkp recognize` on gallery frames (scripts/gallery-eval.sh).

  sift_recognize.py --targets TARGETS.csv FRAME... | --frames LIST [--root DIR]
                    [--ratio 0.8 --max-candidates 5 --min-votes 8
                     --min-inliers 12 --ransac-threshold 5 --robust ransac|magsac
                     --max-target-side 640 --checks 64 --trees 4]

Done the way `mvkp recognize` does it, with SIFT in place of MVKP:
  * every target (TARGETS.csv: id,image[,title], paths relative to the list;
    or a folder of images) is read in grey and, if its longest side exceeds
    --max-target-side, downscaled with INTER_AREA to that size (what
    `mvkp db add` trains on); default cv2.SIFT_create() features; all
    targets' descriptors are pooled in one FLANN KD-tree index, each labelled
    by its target;
  * per frame: SIFT on the grey frame, 2-NN search in the pooled index,
    Lowe ratio test (0.8), each surviving match votes for its target;
  * up to --max-candidates targets with >= max(min_votes, min_inliers) votes,
    most votes first, are verified by cv2.findHomography (RANSAC 5 px, or
    USAC_MAGSAC) on their own matches; accepted with >= 12 inliers and a
    plausible outline (convex, not self-intersecting, area >= 64 px^2, as
    mvkp's IsPlausibleOutline).
Prints one JSON object per frame, like `mvkp recognize --json`: query, found
[{id, homography (target pixels of the original image -> frame), outline,
inliers, votes, score}], keypoints, time_ms {detect (SIFT detect+describe),
search, verify, total}; image decoding is not timed (as in mvkp). Single
threaded (cv2.setNumThreads(1)).
"""
import argparse
import csv
import json
import os
import sys
import time

import cv2
import numpy as np


def read_targets(spec):
    out = []
    if os.path.isdir(spec):
        for f in sorted(os.listdir(spec)):
            if f.lower().endswith((".png", ".jpg", ".jpeg")):
                out.append((os.path.splitext(f)[0], os.path.join(spec, f)))
        return out
    base = os.path.dirname(os.path.abspath(spec))
    with open(spec, newline="") as fh:
        for row in csv.DictReader(fh):
            p = row["image"]
            out.append((row["id"], p if os.path.isabs(p) else os.path.join(base, p)))
    return out


def plausible(q, min_area=64.0):
    if not np.all(np.isfinite(q)) or np.abs(q).max() > 1e6:
        return False
    sign = 0
    for i in range(4):
        a = q[(i + 1) % 4] - q[i]
        b = q[(i + 2) % 4] - q[(i + 1) % 4]
        c = a[0] * b[1] - a[1] * b[0]
        s = 1 if c > 0 else (-1 if c < 0 else 0)
        if s == 0 or (sign and s != sign):
            return False
        sign = s
    return abs(cv2.contourArea(np.float32(q))) >= min_area


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--targets", required=True)
    ap.add_argument("frames", nargs="*")
    ap.add_argument("--frames", dest="frame_list")
    ap.add_argument("--root", default="", help="frame paths in --frames are relative to this folder")
    ap.add_argument("--ratio", type=float, default=0.8)
    ap.add_argument("--max-candidates", type=int, default=5)
    ap.add_argument("--min-votes", type=int, default=8)
    ap.add_argument("--min-inliers", type=int, default=12)
    ap.add_argument("--ransac-threshold", type=float, default=5.0)
    ap.add_argument("--robust", choices=["ransac", "magsac"], default="ransac")
    ap.add_argument("--max-target-side", type=int, default=640)
    ap.add_argument("--trees", type=int, default=4)
    ap.add_argument("--checks", type=int, default=64)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    cv2.setRNGSeed(0x12345678)

    frames = list(a.frames)
    if a.frame_list:
        frames += [l.strip() for l in open(a.frame_list) if l.strip()]
    if not frames:
        sys.exit("sift_recognize: no frames")

    sift = cv2.SIFT_create()
    t0 = time.perf_counter()
    ids, descs, pts, labels, sizes = [], [], [], [], []
    for k, (tid, path) in enumerate(read_targets(a.targets)):
        g = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if g is None:
            sys.exit(f"sift_recognize: cannot read target {path}")
        W, H = g.shape[1], g.shape[0]
        s = 1.0
        if max(W, H) > a.max_target_side:
            s = a.max_target_side / max(W, H)
            g = cv2.resize(g, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
        kp, d = sift.detectAndCompute(g, None)
        if d is None or len(kp) < 4:
            print(f"sift_recognize: target {tid} has no SIFT features; skipped", file=sys.stderr)
            continue
        p = np.float32([q.pt for q in kp])
        if s != 1.0:  # back to the original image's pixels (pixel centres)
            p = (p + 0.5) / np.float32([g.shape[1] / W, g.shape[0] / H]) - 0.5
        ids.append(tid)
        sizes.append((W, H))
        descs.append(d)
        pts.append(p)
        labels.append(np.full(len(kp), len(ids) - 1, np.int32))
    D = np.vstack(descs).astype(np.float32)
    P = np.vstack(pts)
    L = np.concatenate(labels)
    flann = cv2.FlannBasedMatcher({"algorithm": 1, "trees": a.trees}, {"checks": a.checks})
    flann.add([D])
    flann.train()
    load_ms = (time.perf_counter() - t0) * 1e3
    print(f"sift_recognize: {len(ids)} targets, {len(D)} descriptors, index in {load_ms:.0f} ms", file=sys.stderr)

    method = cv2.RANSAC if a.robust == "ransac" else cv2.USAC_MAGSAC
    need = max(a.min_votes, a.min_inliers)
    fails = 0
    for f in frames:
        path = os.path.join(a.root, f) if a.root and not os.path.isabs(f) else f
        g = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if g is None:
            fails += 1
            print(json.dumps({"query": f, "error": "cannot read"}), flush=True)
            continue
        t1 = time.perf_counter()
        kp, d = sift.detectAndCompute(g, None)
        t2 = time.perf_counter()
        found = []
        if d is not None and len(kp) >= 2:
            qpts = np.float32([q.pt for q in kp])
            mm = flann.knnMatch(d.astype(np.float32), k=2)
            qi, ti = [], []
            for m in mm:
                if len(m) == 2 and m[0].distance < a.ratio * m[1].distance:
                    qi.append(m[0].queryIdx)
                    ti.append(m[0].trainIdx)
            qi, ti = np.int32(qi), np.int32(ti)
            lab = L[ti] if len(ti) else np.int32([])
            t3 = time.perf_counter()
            if len(lab):
                cnt = np.bincount(lab, minlength=len(ids))
                cand = [int(c) for c in np.argsort(-cnt, kind="stable") if cnt[c] >= need][: a.max_candidates]
                for c in cand:
                    sel = lab == c
                    src, dst = P[ti[sel]], qpts[qi[sel]]
                    cv2.setRNGSeed(0x12345678)
                    Hm, mask = cv2.findHomography(src, dst, method, a.ransac_threshold, maxIters=2000,
                                                  confidence=0.995)
                    if Hm is None:
                        continue
                    inl = int(mask.sum())
                    if inl < a.min_inliers:
                        continue
                    W, H = sizes[c]
                    quad = cv2.perspectiveTransform(np.float32([[[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]]),
                                                    Hm)[0]
                    if not plausible(quad.astype(np.float64)):
                        continue
                    found.append({"id": ids[c], "homography": Hm.tolist(), "outline": quad.tolist(), "inliers": inl,
                                  "votes": int(cnt[c]), "score": inl / float(cnt[c])})
        else:
            t3 = time.perf_counter()
        t4 = time.perf_counter()
        ms = lambda x, y: round((y - x) * 1e3, 3)
        print(json.dumps({"query": f, "found": found, "keypoints": len(kp),
                          "time_ms": {"detect": ms(t1, t2), "search": ms(t2, t3), "verify": ms(t3, t4),
                                      "total": ms(t1, t4)},
                          "targets": len(ids), "load_ms": round(load_ms, 1)}), flush=True)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
