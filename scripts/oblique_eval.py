#!/usr/bin/env python3
"""Oblique view <-> nadir photo registration, scored on synthetic cities (issue 22).

Generates cities with oblique views (`mvkp synth-oblique`), then registers each
oblique view to its city's nadir photo with every method and scores the answer
on the view's check points (visible roof corners and open ground, exact):

  homography methods  the nadir -> oblique homography maps each check point's
                      nadir pixel; error = mean distance to its oblique pixel;
  camera methods      the matches' nadir pixels are lifted to 3-D through the
                      nadir photo's registration to the LiDAR (x, y from it, z
                      from the DSM, the photo's lean undone), and the oblique
                      camera is solved by PnP + RANSAC (K known); error = mean
                      reprojection error of the check points' 3-D positions.

Success: error <= 5 px. A method that gives no answer is "none", never wrong.
Stage 1 (nadir -> depth) is taken from the city's ground truth here, so the
table isolates stage 2; `--stage1 mvkp` runs `mvkp register` instead.

Methods: sift-h, orb-h (OpenCV, ratio test + RANSAC homography), sift-pnp,
mvkp-h (`mvkp pair NADIR OBLIQUE --json`, its homography), mvkp-pnp (its
verified correspondences lifted and solved by PnP here), mvkp-view (the
product: `mvkp register-all DEPTH NADIR VIEW... --stage1 STAGE1 --json`, the
same per view as `mvkp register-view`; stage 1 as --stage1 says), fusion-view
and auto-view (the same with --method fusion / auto). Their time per view is
the view's own plus its share of the nadir photo's training.

    scripts/oblique_eval.py --mvkp build/mvkp --out out/oblique --style dense --seed 1 --n 4 --views 4
    scripts/oblique_eval.py --aggregate out/oblique*/summary.json   # one table over several runs
"""
import argparse
import collections
import json
import os
import statistics
import subprocess
import sys
import time

import cv2
import numpy as np

TILT_BINS = [(30, 45), (45, 60)]
VIEW_METHODS = {"mvkp-view": "mvkp", "fusion-view": "fusion", "auto-view": "auto"}  # register-all --method


def apply_h(H, pts):
    p = np.hstack([pts, np.ones((len(pts), 1))]) @ H.T
    return p[:, :2] / p[:, 2:3]


def project(P, X):
    p = np.hstack([X, np.ones((len(X), 1))]) @ P.T
    return p[:, :2] / p[:, 2:3]


class City:
    def __init__(self, d):
        self.dir = d
        self.truth = json.load(open(os.path.join(d, "truth.json")))
        self.res = self.truth["res_m"]
        self.depth = cv2.imread(os.path.join(d, "depth.tif"), cv2.IMREAD_UNCHANGED).astype(np.float32)
        ids = cv2.imread(os.path.join(d, "building_id.png"), cv2.IMREAD_UNCHANGED)
        self.lean_px = np.array(self.truth.get("lean_m_per_m", [0, 0])) / self.res
        self.H = np.array(self.truth["photo_to_depth"], dtype=np.float64)  # nadir px -> depth px (stage 1)
        # terrain: open ground, block medians, smoothed
        open_ = np.isfinite(self.depth) & (ids == 0)
        b = 25
        h, w = self.depth.shape
        gh, gw = (h + b - 1) // b, (w + b - 1) // b
        grid = np.full((gh, gw), np.nan, np.float32)
        for i in range(gh):
            for j in range(gw):
                v = self.depth[i * b:(i + 1) * b, j * b:(j + 1) * b][open_[i * b:(i + 1) * b, j * b:(j + 1) * b]]
                if v.size:
                    grid[i, j] = np.median(v)
        fill = np.nanmedian(grid) if np.isfinite(grid).any() else 0.0
        grid[~np.isfinite(grid)] = fill
        self.terrain = cv2.resize(grid, (w, h), interpolation=cv2.INTER_LINEAR)
        dsm = self.depth.copy()
        dsm[~np.isfinite(dsm)] = self.terrain[~np.isfinite(dsm)]
        self.dsm = dsm

    def lift(self, nadir_px):
        """Nadir photo pixels -> world metres (east, north, up): the first surface
        point met going down the lean from above, i.e. the highest height t
        whose depth point q = H(p) - t * lean stands at least t above the
        terrain (as the leaning orthophoto shows it)."""
        q0 = apply_h(self.H, nadir_px)
        h, w = self.dsm.shape
        above = self.dsm - self.terrain
        found = np.full(len(q0), -1.0)
        if np.linalg.norm(self.lean_px) > 1e-9:
            for t in np.arange(min(80.0, float(np.nanmax(above))), 0.0, -0.25):
                q = q0 - t * self.lean_px[None, :]
                c = np.clip(np.round(q).astype(int), [0, 0], [w - 1, h - 1])
                hit = (found < 0) & (above[c[:, 1], c[:, 0]] >= t)
                found[hit] = t
        t = np.maximum(found, 0)
        q = q0 - t[:, None] * self.lean_px[None, :]
        c = np.clip(np.round(q).astype(int), [0, 0], [w - 1, h - 1])
        z = self.dsm[c[:, 1], c[:, 0]]
        inside = (q[:, 0] >= 0) & (q[:, 1] >= 0) & (q[:, 0] <= w - 1) & (q[:, 1] <= h - 1)
        return np.column_stack([q[:, 0] * self.res, -q[:, 1] * self.res, z]), inside  # east, north, up


def ratio_matches(det, a, b, ratio=0.8, cross=False):
    ka, da = det.detectAndCompute(a, None)
    kb, db = det.detectAndCompute(b, None)
    if da is None or db is None or len(ka) < 4 or len(kb) < 4:
        return np.zeros((0, 2)), np.zeros((0, 2))
    norm = cv2.NORM_HAMMING if da.dtype == np.uint8 else cv2.NORM_L2
    m = cv2.BFMatcher(norm).knnMatch(da, db, k=2)
    good = [x[0] for x in m if len(x) == 2 and x[0].distance < ratio * x[1].distance]
    pa = np.float64([ka[g.queryIdx].pt for g in good]).reshape(-1, 2)
    pb = np.float64([kb[g.trainIdx].pt for g in good]).reshape(-1, 2)
    return pa, pb


def homography(pa, pb):
    if len(pa) < 8:
        return None
    H, inl = cv2.findHomography(pa, pb, cv2.RANSAC, 4.0, maxIters=5000, confidence=0.999)
    if H is None or inl is None or inl.sum() < 8:
        return None
    return H


def pnp(city, K, pa, pb):
    """Camera from nadir/oblique pixel pairs: lift, PnP + RANSAC, refine."""
    if len(pa) < 8:
        return None
    X, inside = city.lift(pa)
    X, pb = X[inside], pb[inside]
    if len(X) < 8:
        return None
    ok, rvec, tvec, inl = cv2.solvePnPRansac(X, pb, K, None, reprojectionError=4.0, iterationsCount=10000,
                                             confidence=0.9999, flags=cv2.SOLVEPNP_AP3P)
    if not ok or inl is None or len(inl) < 12:
        return None
    inl = inl.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(X[inl], pb[inl], K, None, rvec, tvec)
    R, _ = cv2.Rodrigues(rvec)
    return K @ np.hstack([R, tvec.reshape(3, 1)])


def mvkp_pair(mvkp, nadir, oblique):
    p = subprocess.run([mvkp, "pair", nadir, oblique, "--json"], capture_output=True, text=True)
    try:
        j = json.loads(p.stdout)
    except ValueError:
        return None, np.zeros((0, 2)), np.zeros((0, 2))
    H = np.array(j["homography"], dtype=np.float64).reshape(3, 3) if j.get("homography") else None
    m = np.array(j.get("matches") or [], dtype=np.float64).reshape(-1, 6) if j.get("matches") else np.zeros((0, 6))
    m = m[m[:, 5] > 0] if len(m) else m  # the matches its verification kept
    return H, m[:, 0:2], m[:, 2:4]


def aggregate(paths):
    """Per-tilt table over several runs' summary files (every method they share)."""
    rows, methods = [], None
    for p in paths:
        s = json.load(open(p))
        rows += s["rows"]
        methods = [m for m in s["summary"]["methods"] if methods is None or m in methods]
    print("| tilt | views | " + " | ".join(methods) + " |")
    print("|---|---|" + "---|" * len(methods))
    for lo, hi in TILT_BINS + [(30, 60)]:
        sel = [r for r in rows if lo <= r["tilt"] < hi or (hi == 60 and r["tilt"] == 60)]
        cells = []
        for m in methods:
            errs = [r[m]["error_px"] for r in sel if r[m]["error_px"] is not None]
            ok = [e for e in errs if e <= 5]
            view_ms = [r[m].get("view_ms", r[m]["ms"]) for r in sel]
            ms = [r[m]["ms"] for r in sel]
            cells.append("%d (%.0f %%), %d wrong, %s px; %.0f / %.0f ms" % (
                len(ok), 100.0 * len(ok) / max(1, len(sel)), len(errs) - len(ok),
                "%.2f" % statistics.median(ok) if ok else "-", statistics.median(view_ms) if view_ms else 0,
                statistics.median(ms) if ms else 0))
        print("| %d-%d° | %d | %s |" % (lo, hi, len(sel), " | ".join(cells)))
    print("\ncells: right (share), wrong, median error of the right ones; median ms per view without / with "
          "its share of training")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--aggregate":
        return aggregate(sys.argv[2:])
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mvkp", default="build/mvkp")
    ap.add_argument("--out", required=True)
    ap.add_argument("--style", default="dense")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--n", type=int, default=4, help="cities")
    ap.add_argument("--views", type=int, default=4, help="oblique views per city")
    ap.add_argument("--methods", default="sift-h,orb-h,sift-pnp,mvkp-h,mvkp-pnp,mvkp-view")
    ap.add_argument("--stage1", choices=["truth", "mvkp"], default="truth",
                    help="stage 1 for mvkp-, fusion- and auto-view: the city's truth, or mvkp register's answer (views of cities it "
                         "does not register get none)")
    ap.add_argument("--reuse", action="store_true", help="score views already in --out")
    ap.add_argument("--view-args", default="", help="more arguments for mvkp register-all (mvkp-, fusion-, auto-view)")
    ap.add_argument("--tag", default="", help="summary file name: summary<tag>.json")
    a = ap.parse_args()
    methods = [m.strip() for m in a.methods.split(",") if m.strip()]
    if not a.reuse:
        subprocess.run([a.mvkp, "synth-oblique", "-o", a.out, "--n", str(a.n), "--views", str(a.views), "--style",
                        a.style, "--seed", str(a.seed)], check=True, stdout=subprocess.DEVNULL)
    sift, orb = cv2.SIFT_create(4000), cv2.ORB_create(4000)
    rows = []
    for cd in sorted(d for d in os.listdir(a.out) if d.startswith("city_")):
        cdir = os.path.join(a.out, cd)
        city = City(cdir)
        nadir_path = os.path.join(cdir, "photo.png")
        nadir = cv2.imread(nadir_path, cv2.IMREAD_GRAYSCALE)
        stage1 = os.path.join(cdir, "stage1_%s.json" % a.stage1)
        view_methods = [m for m in methods if m in VIEW_METHODS]
        if view_methods and not os.path.exists(stage1):
            if a.stage1 == "truth":
                t = city.truth
                json.dump({"homography": t["photo_to_depth"], "lean_depth_px_per_m": city.lean_px.tolist(),
                           "depth": {"size": t["depth_size"], "res_m": t["res_m"]},
                           "photo": {"size": t["photo_size"]}}, open(stage1, "w"))
            else:
                r = subprocess.run([a.mvkp, "register", os.path.join(cdir, "depth.tif"), nadir_path, "--json"],
                                   capture_output=True, text=True)
                open(stage1, "w").write(r.stdout)
        view_jsons = sorted(f for f in os.listdir(cdir) if f.startswith("oblique_") and f.endswith(".json"))
        all_views = {}  # (method, view image) -> register-all's answer for it, and its share of the training
        for vm in view_methods:
            images = [os.path.join(cdir, json.load(open(os.path.join(cdir, f)))["image"]) for f in view_jsons]
            t0 = time.perf_counter()
            r = subprocess.run([a.mvkp, "register-all", os.path.join(cdir, "depth.tif"), nadir_path] + images +
                               ["--stage1", stage1, "--json", "--res", str(city.res), "--method", VIEW_METHODS[vm]] +
                               a.view_args.split(), capture_output=True, text=True)
            wall_ms = (time.perf_counter() - t0) * 1000
            try:
                j = json.loads(r.stdout)
            except ValueError:
                j = None  # stage 1 gave no registration (not JSON): no answers
            if j:
                for v in j["views"]:
                    v["train_share_ms"] = j["time_ms"]["train"] / max(1, len(j["views"]))
                    all_views[(vm, os.path.abspath(v["view"]))] = v
                print(json.dumps({"city": cd, "method": vm, "train_ms": round(j["time_ms"]["train"]),
                                  "wall_ms": round(wall_ms)}), flush=True)
        for vj in view_jsons:
            v = json.load(open(os.path.join(cdir, vj)))
            opath = os.path.join(cdir, v["image"])
            obl = cv2.imread(opath, cv2.IMREAD_GRAYSCALE)
            K = np.array(v["K"], dtype=np.float64)
            cps = v["check_points"]
            if len(cps) < 5:
                continue
            npx = np.array([c["nadir_px"] for c in cps], dtype=np.float64)
            opx = np.array([c["oblique_px"] for c in cps], dtype=np.float64)
            Xw = np.array([c["world_m"] for c in cps], dtype=np.float64)
            row = {"view": os.path.join(cd, v["image"]), "tilt": v["options"]["tilt_deg"],
                   "gsd": v["options"]["gsd_m"], "checks": len(cps)}
            cache = {}
            for m in methods:
                t0 = time.perf_counter()
                err = None
                if m in ("sift-h", "sift-pnp"):
                    if "sift" not in cache:
                        cache["sift"] = ratio_matches(sift, nadir, obl)
                        cache["sift_ms"] = (time.perf_counter() - t0) * 1000
                    elif m == "sift-pnp":
                        t0 -= cache["sift_ms"] / 1000  # the matching is part of its time
                    pa, pb = cache["sift"]
                    if m == "sift-h":
                        H = homography(pa, pb)
                        err = None if H is None else float(np.linalg.norm(apply_h(H, npx) - opx, axis=1).mean())
                    else:
                        P = pnp(city, K, pa, pb)
                        err = None if P is None else float(np.linalg.norm(project(P, Xw) - opx, axis=1).mean())
                elif m == "orb-h":
                    pa, pb = ratio_matches(orb, nadir, obl)
                    H = homography(pa, pb)
                    err = None if H is None else float(np.linalg.norm(apply_h(H, npx) - opx, axis=1).mean())
                elif m in ("mvkp-h", "mvkp-pnp"):
                    if "mvkp" not in cache:
                        cache["mvkp"] = mvkp_pair(a.mvkp, nadir_path, opath)
                        cache["mvkp_ms"] = (time.perf_counter() - t0) * 1000
                    elif m == "mvkp-pnp":
                        t0 -= cache["mvkp_ms"] / 1000
                    H, pa, pb = cache["mvkp"]
                    if m == "mvkp-h":
                        err = None if H is None else float(np.linalg.norm(apply_h(H, npx) - opx, axis=1).mean())
                    else:
                        P = pnp(city, K, pa, pb)
                        err = None if P is None else float(np.linalg.norm(project(P, Xw) - opx, axis=1).mean())
                elif m in VIEW_METHODS:
                    j = all_views.get((m, os.path.abspath(opath)), {})
                    if j.get("camera"):
                        err = float(np.linalg.norm(project(np.array(j["camera"]), Xw) - opx, axis=1).mean())
                    # the view's own time plus its share of the nadir photo's training
                    row[m] = {"error_px": err, "view_ms": j.get("time_ms", {}).get("total", 0),
                              **{k: j.get(k) for k in ("inliers", "lifted", "inlier_tiles", "inlier_cells",
                                                       "inlier_height_span_m", "nadir_gsd_m", "rms_px",
                                                       "scale", "refinement", "outline_refinement", "method", "fusion")},
                              "ms": j.get("time_ms", {}).get("total", 0) + j.get("train_share_ms", 0)}
                    continue
                row[m] = {"error_px": err, "ms": (time.perf_counter() - t0) * 1000}
            rows.append(row)
            print(json.dumps({"view": row["view"], "tilt": round(row["tilt"], 1),
                              **{m: (None if row[m]["error_px"] is None else round(row[m]["error_px"], 2))
                                 for m in methods}}), flush=True)
    # table per tilt bin
    print("\n| tilt | views | " + " | ".join(methods) + " |")
    print("|---|---|" + "---|" * len(methods))
    summary = {"style": a.style, "seed": a.seed, "methods": methods, "bins": {}}
    for lo, hi in TILT_BINS:
        sel = [r for r in rows if lo <= r["tilt"] < hi or (hi == 60 and r["tilt"] == 60)]
        cells = []
        for m in methods:
            ok = sum(1 for r in sel if r[m]["error_px"] is not None and r[m]["error_px"] <= 5)
            wrong = sum(1 for r in sel if r[m]["error_px"] is not None and r[m]["error_px"] > 5)
            errs = [r[m]["error_px"] for r in sel if r[m]["error_px"] is not None and r[m]["error_px"] <= 5]
            ms = [r[m]["ms"] for r in sel]
            cells.append("%d/%d ok, %d wrong, median %s px, %.0f ms" % (
                ok, len(sel), wrong, "%.2f" % statistics.median(errs) if errs else "-",
                statistics.median(ms) if ms else 0))
            summary["bins"].setdefault("%d-%d" % (lo, hi), {})[m] = {"views": len(sel), "ok": ok, "wrong": wrong}
        print("| %d-%d° | %d | %s |" % (lo, hi, len(sel), " | ".join(cells)))
    json.dump({"rows": rows, "summary": summary}, open(os.path.join(a.out, "summary%s.json" % a.tag), "w"), indent=1)


if __name__ == "__main__":
    sys.exit(main())
