#!/usr/bin/env python3
"""Evaluation of `mvkp register` (issue 8) on generated cities and the real
Montpellier tile, with OpenCV SIFT and ORB between the photo and the
normalised depth image as the texture baseline, in the same run.

  scripts/aerial_eval.py --mvkp build/mvkp --out out/aerial [--n 50] [--seed 1]
                         [--real ../shared/data/aerial/montpellier] [--no-baseline]
                         [--style classic|suburb|dense|civic|mix|a,b,...] [--size 200]
                         [--buildings 3-6] [--jobs 2]

Styles (issue 21; `mvkp synth-city --style`, docs/aerial.md "Test data"): with
one style other than classic the scenes go to OUT/scenes_STYLE/; `mix` (= the
three new styles) or a comma list cycles the styles by scene index, scene i of
style k being scene i // len(styles) of that style's own set (same seed).
classic keeps OUT/scenes/ and the output it always had; the tables below are
printed after it.

Scale convention of the tables: photo px per depth px = 1 / truth "scale"
(synth-city's scale is depth px per photo px). 0.3 means a coarse photo (houses
5-8 photo px across at 0.5 m depth), 3 a fine one. Bins 0.3-0.5, 0.5-1, 1-2, 2-3.4.
Counts per bin and per style: success (ok and <= 5 px), WRONG (ok and > 5 px:
reported as a success but wrong, listed with their errors and scene dirs), no
answer. `confidence` is shown when register's JSON has it. A third table counts
by the ground-truth buildings wholly inside the photo (0-1, 2, 3-5, 6+): how
much the photo shows to register on.

Per generated scene (mvkp synth-city: ~30 buildings, 1000x1000 depth at
0.5 m, photo at any rotation, scale 0.3-3, mild perspective):
  success: `register` says ok and the mean error of the ground-truth building
    corners that the photo shows, mapped photo -> depth by the estimate, is
    <= 5 px at depth resolution. An ok answer with a larger error is a WRONG
    registration (worse than "no registration found").
  APE: the mean corner error of the successes.
  time per stage (register's time_ms) and peak memory (its peak RSS).
  depth segmentation: buildings found (a region with IoU >= 0.5 against the
    building's footprint in building_id.png) and false regions (no building
    covers half of the region).
Negative scenes (--negatives, photos of ground next to the depth image):
  any ok answer is a false registration.
Real tile: the orthophoto (0.2 m) onto the nDSM (0.5 m); the truth comes
  from the two georeferences (the photo leans ~6 px, see its README).
"""
import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys
import time

import cv2
import numpy as np


def run_json(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        return None, r.stderr.strip()
    return json.loads(r.stdout.strip().splitlines()[-1]), ""


def h_of(x):
    return np.array(x, dtype=np.float64).reshape(3, 3)


def apply(H, pts):
    p = np.hstack([pts, np.ones((len(pts), 1))]) @ H.T
    return p[:, :2] / p[:, 2:3]


def corner_error(H_est, H_true, corners_depth, photo_size):
    """Mean |H_est(H_true^-1 c) - c| over the corners the photo shows."""
    c = np.array(corners_depth, dtype=np.float64).reshape(-1, 2)
    cp = apply(np.linalg.inv(H_true), c)
    w, h = photo_size
    vis = (cp[:, 0] >= 0) & (cp[:, 0] <= w - 1) & (cp[:, 1] >= 0) & (cp[:, 1] <= h - 1)
    if not vis.any():
        return None, 0
    e = np.linalg.norm(apply(H_est, cp[vis]) - c[vis], axis=1)
    return float(e.mean()), int(vis.sum())


SCALE_BINS = [(0.3, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 3.4)]
NEW_STYLES = ["suburb", "dense", "civic"]
# Ground-truth buildings wholly in the photo (inclusive bins): with 0-1 a
# pose rests on parts of buildings, or on one outline that fits any similar
# rectangle.
BUILDING_BINS = [(0, 1), (2, 2), (3, 5), (6, 10**9)]


def styles_of(arg):
    if arg == "mix":
        return list(NEW_STYLES)
    return [x.strip() for x in arg.split(",") if x.strip()]


def scene_dir(out, style, index, negative=False):
    base = ("negatives" if negative else "scenes") + ("" if style == "classic" else "_" + style)
    return os.path.join(out, base, "city_%04d" % index)


def photo_px_per_depth_px(row):
    return 1.0 / row["scale"]


def bin_of(v):
    for lo, hi in SCALE_BINS:
        if lo <= v < hi:
            return "%g-%g" % (lo, hi)
    return "<%g" % SCALE_BINS[0][0] if v < SCALE_BINS[0][0] else ">=%g" % SCALE_BINS[-1][1]


def tally(rows):
    succ = [r for r in rows if r["success"]]
    wrong = [r for r in rows if r.get("ok") and not r["success"]]
    times = [r["time_ms"]["total"] for r in rows if "time_ms" in r]
    return {"n": len(rows), "success": len(succ), "wrong": len(wrong), "no_answer": sum(1 for r in rows if not r.get("ok")),
            "ape_px": statistics.mean(r["corner_error"] for r in succ) if succ else None,
            "time_ms_median": statistics.median(times) if times else None,
            "peak_rss_mb_max": max((r["peak_rss_mb"] for r in rows if "peak_rss_mb" in r), default=None)}


def print_tables(rows, out_json):
    """Per style and per scale bin, then every wrong answer."""
    def line(name, t):
        ape = "%.2f" % t["ape_px"] if t["ape_px"] is not None else "-"
        tm = "%.0f" % t["time_ms_median"] if t["time_ms_median"] is not None else "-"
        rss = "%.1f" % t["peak_rss_mb_max"] if t["peak_rss_mb_max"] is not None else "-"
        pct = 100.0 * t["success"] / t["n"] if t["n"] else 0
        return "%-14s %4d %5d (%3.0f%%) %6d %9d %7s %9s %8s" % (name, t["n"], t["success"], pct, t["wrong"], t["no_answer"],
                                                            ape, tm, rss)
    head = "%-14s %4s %12s %6s %9s %7s %9s %8s" % ("", "n", "success<=5px", "WRONG", "no answer", "APE px", "median ms",
                                                  "peak MB")
    out_json["per_style"], out_json["per_scale_bin"] = {}, {}
    print("\nper style")
    print(head)
    for st in sorted({r["style"] for r in rows}):
        t = tally([r for r in rows if r["style"] == st])
        out_json["per_style"][st] = t
        print(line(st, t))
    t = tally(rows)
    print(line("all", t))
    print("\nper scale bin (photo px per depth px = 1 / synth-city scale)")
    print(head)
    for lo, hi in SCALE_BINS + [(None, None)]:
        if lo is None:
            sel = [r for r in rows if not any(a <= photo_px_per_depth_px(r) < b for a, b in SCALE_BINS)]
            name = "outside"
            if not sel:
                continue
        else:
            sel = [r for r in rows if lo <= photo_px_per_depth_px(r) < hi]
            name = "%g-%g" % (lo, hi)
        t = tally(sel)
        out_json["per_scale_bin"][name] = t
        print(line(name, t))
    out_json["per_buildings_in_view"] = {}
    print("\nper buildings in view (ground-truth footprints wholly inside the photo)")
    print(head)
    for lo, hi in BUILDING_BINS:
        sel = [r for r in rows if lo <= r.get("buildings_in_view", 0) <= hi]
        if not sel:
            continue
        name = "%d" % lo if lo == hi else ("%d+" % lo if hi > 999 else "%d-%d" % (lo, hi))
        t = tally(sel)
        out_json["per_buildings_in_view"][name] = t
        print(line(name, t))
    wrong = [r for r in rows if r.get("ok") and not r["success"]]
    out_json["wrong_list"] = [{"dir": r["dir"], "style": r["style"], "corner_error": r.get("corner_error"),
                               "roof_corner_error": r.get("roof_corner_error"),
                               "photo_px_per_depth_px": photo_px_per_depth_px(r), "model": r.get("model"),
                               "confidence": r.get("confidence")} for r in wrong]
    has_conf = any(r.get("confidence") is not None for r in rows)
    print("\nWRONG, reported as success (%d)%s" % (len(wrong), "" if wrong else ": none"))
    for r in wrong:
        err = "%.1f px" % r["corner_error"] if r.get("corner_error") is not None else "no corner in view"
        conf = "  confidence %.3g" % r["confidence"] if has_conf and r.get("confidence") is not None else ""
        if r.get("roof_corner_error") is not None:
            err += " (roofs %.1f px)" % r["roof_corner_error"]
        print("  %s  %s  photo/depth px %.2f  rot %.0f  model %s  regions %s%s" % (
            r["dir"], err, photo_px_per_depth_px(r), r["rotation_deg"], r.get("model"), r.get("regions"), conf))
    if has_conf:
        print("\nconfidence (per scene): success / wrong / no answer")
        for r in rows:
            if r.get("confidence") is not None:
                kind = "success" if r["success"] else "WRONG" if r.get("ok") else "none"
                print("  %-40s %-8s %.3g" % (r["dir"], kind, r["confidence"]))


def buildings_in_view(truth):
    """Ground-truth buildings whose whole footprint the photo shows: what a
    registration can rest on (1 building fits any similar rectangle)."""
    Hi = np.linalg.inv(h_of(truth["photo_to_depth"]))
    w, h = truth["photo_size"]
    n = 0
    for b in truth.get("buildings", []):
        p = apply(Hi, np.array(b["footprint"], dtype=np.float64).reshape(-1, 2))
        n += bool(((p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1)).all())
    return n


def normalised_depth(depth):
    z = depth.copy()
    ok = np.isfinite(z)
    lo, hi = np.percentile(z[ok], 1), np.percentile(z[ok], 99.5)
    z[~ok] = lo
    return np.clip((z - lo) / max(hi - lo, 1e-6) * 255, 0, 255).astype(np.uint8)


def baseline(kind, photo_gray, depth_u8):
    """Texture matching photo -> normalised depth: features + ratio 0.8 + RANSAC."""
    t = time.perf_counter()
    if kind == "sift":
        det = cv2.SIFT_create()
        norm = cv2.NORM_L2
    else:
        det = cv2.ORB_create(4000)
        norm = cv2.NORM_HAMMING
    k1, d1 = det.detectAndCompute(photo_gray, None)
    k2, d2 = det.detectAndCompute(depth_u8, None)
    H = None
    if d1 is not None and d2 is not None and len(k1) >= 4 and len(k2) >= 4:
        m = cv2.BFMatcher(norm).knnMatch(d1, d2, k=2)
        good = [a for a, *b in m if b and a.distance < 0.8 * b[0].distance]
        if len(good) >= 4:
            src = np.float32([k1[g.queryIdx].pt for g in good])
            dst = np.float32([k2[g.trainIdx].pt for g in good])
            H, inl = cv2.findHomography(src, dst, cv2.RANSAC, 5.0)
            if H is not None and (inl is None or int(inl.sum()) < 8):
                H = None
    return H, (time.perf_counter() - t) * 1000


def segmentation_score(regions, building_id):
    """Buildings with a region of IoU >= 0.5; regions no building covers by half."""
    ids = building_id.astype(np.int32) - 1  # 16-bit id+1, 0 = none
    n_b = int(ids.max()) + 1 if ids.max() >= 0 else 0
    areas = np.bincount(ids[ids >= 0].ravel(), minlength=n_b)
    found = set()
    false = 0
    for r in regions:
        mask = np.zeros(ids.shape, np.uint8)
        cv2.fillPoly(mask, [np.array(r["contour"], np.int32).reshape(-1, 1, 2)], 1)
        inside = ids[mask > 0]
        if inside.size == 0:
            false += 1
            continue
        cnt = np.bincount(inside[inside >= 0], minlength=n_b)
        best = int(cnt.argmax()) if cnt.size else -1
        if best < 0 or cnt[best] < 0.5 * inside.size:
            false += 1
            continue
        iou = cnt[best] / float(inside.size + areas[best] - cnt[best])
        if iou >= 0.5:
            found.add(best)
    present = int((areas > 0).sum())
    return len(found), present, false, len(regions)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mvkp", default="build/mvkp")
    ap.add_argument("--out", default="out/aerial")
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--negatives", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--real", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "aerial", "montpellier"))
    ap.add_argument("--no-baseline", action="store_true")
    ap.add_argument("--draw", type=int, default=4, help="draw the registration of the first N scenes (register.png)")
    ap.add_argument("--synth-args", default="", help="extra arguments for `mvkp synth-city` (one string), e.g. "
                    "'--sun-elevation 90' for the same scenes without shadows")
    ap.add_argument("--register-args", default="", help="extra arguments for every `mvkp register` (one string)")
    ap.add_argument("--style", default="classic", help="classic, suburb, dense, civic, mix (the three new ones) or a "
                    "comma list; several styles are cycled by scene index")
    ap.add_argument("--size", default=None, help="depth raster size, W or WxH (synth-city default 1000)")
    ap.add_argument("--buildings", default=None, help="buildings in the depth raster, N or MIN-MAX (per scene)")
    ap.add_argument("--trees", type=int, default=None, help="trees in the depth raster (default: synth-city's 60 "
                    "per 1000x1000, scaled to --size)")
    ap.add_argument("--jobs", type=int, default=1, help="registrations run at once (times are then not idle times)")
    ap.add_argument("--no-real", action="store_true", help="skip the real tile")
    ap.add_argument("--no-segmentation", action="store_true", help="skip the depth segmentation score")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    styles = styles_of(a.style)
    gen = []
    if a.size:
        w, _, h = a.size.partition("x")
        gen += ["--width", w, "--height", h or w]
        if a.trees is None:
            a.trees = max(4, round(60 * int(w) * int(h or w) / 1e6))
    if a.trees is not None:
        gen += ["--trees", str(a.trees)]
    if a.buildings:
        lo, _, hi = a.buildings.partition("-")
        gen += ["--buildings", lo] + (["--max-buildings", hi] if hi else [])
    gen += a.synth_args.split()
    n_styles = len(styles)
    for si, st in enumerate(styles):
        n_st = len(range(si, a.n, n_styles))
        scenes = os.path.dirname(scene_dir(a.out, st, 0))
        sty = [] if st == "classic" else ["--style", st]
        if n_st and not os.path.isdir(os.path.join(scenes, "city_%04d" % (n_st - 1))):
            subprocess.run([a.mvkp, "synth-city", "-o", scenes, "--n", str(n_st), "--seed", str(a.seed)] + gen + sty,
                           check=True, stdout=subprocess.DEVNULL)
        n_neg = len(range(si, a.negatives, n_styles))
        negs = os.path.dirname(scene_dir(a.out, st, 0, negative=True))
        if n_neg and not os.path.isdir(os.path.join(negs, "city_%04d" % (n_neg - 1))):
            subprocess.run([a.mvkp, "synth-city", "-o", negs, "--n", str(n_neg), "--seed", str(a.seed + 1000),
                            "--no-overlap"] + gen + sty, check=True, stdout=subprocess.DEVNULL)

    def where(i, negative=False):
        return styles[i % n_styles], scene_dir(a.out, styles[i % n_styles], i // n_styles, negative)

    xargs = a.register_args.split()
    rows = []
    base = {"sift": [], "orb": []}
    seg = [0, 0, 0, 0]

    def register(i, negative=False):
        d = where(i, negative)[1]
        # timed and measured without --draw (the drawing keeps the full-size photo)
        return run_json([a.mvkp, "register", os.path.join(d, "depth.tif"), os.path.join(d, "photo.png"), "--json"] + xargs)

    pool = concurrent.futures.ThreadPoolExecutor(max(1, a.jobs))
    futures = [pool.submit(register, i) for i in range(a.n)]
    neg_futures = [pool.submit(register, i, True) for i in range(a.negatives)]
    for i in range(a.n):
        style, d = where(i)
        truth = json.load(open(os.path.join(d, "truth.json")))
        Ht = h_of(truth["photo_to_depth"])
        psize = truth["photo_size"]
        j, err = futures[i].result()
        # the first few scenes are drawn in a second run
        if i < a.draw:
            run_json([a.mvkp, "register", os.path.join(d, "depth.tif"), os.path.join(d, "photo.png"), "--json",
                      "--draw", os.path.join(d, "register.png")] + xargs)
        row = {"scene": i, "scale": truth["scale"], "rotation_deg": truth["rotation_deg"],
               "depth_overlap": truth["depth_overlap"], "style": style, "dir": d,
               "buildings_in_view": buildings_in_view(truth)}
        if j is None:
            row.update(ok=False, error=err)
        else:
            row.update(ok=j["ok"], reason=j["reason"], model=j["model"], time_ms=j["time_ms"], peak_rss_mb=j["peak_rss_mb"], edge=j.get("edge"),
                       peak_rss_above_start_mb=j.get("peak_rss_above_start_mb"), regions=j["regions"])
            if j.get("confidence") is not None:
                row["confidence"] = j["confidence"]
            if j.get("shadows"):
                row["shadow_fallback"] = bool(j["shadows"].get("fallback_answer"))
            if j.get("cast_shadows"):
                row["cast_shadows"] = j["cast_shadows"]
            if j["ok"]:
                e, nvis = corner_error(h_of(j["homography"]), Ht, truth["corners"], psize)
                row.update(corner_error=e, corners_visible=nvis, homography=j["homography"])
                if "lean_m_per_m" in truth:
                    # styles lean (conventional ortho): the error of the roof outlines as the photo shows
                    # them, each footprint moved by height * lean; a fit to the roofs is off by this much less
                    lean = np.array(truth["lean_m_per_m"]) / truth["res_m"]
                    roofs = [np.array(p) + b["height_m"] * lean for b in truth["buildings"] for p in b["footprint"]]
                    row["roof_corner_error"] = corner_error(h_of(j["homography"]), Ht, roofs, psize)[0]
        row["success"] = bool(row.get("ok") and row.get("corner_error") is not None and row["corner_error"] <= 5.0)
        rows.append(row)
        s = None
        if not a.no_segmentation:
            s, _ = run_json([a.mvkp, "segment", "depth", os.path.join(d, "depth.tif"), "--json"])
        if s is not None:
            bid = cv2.imread(os.path.join(d, "building_id.png"), cv2.IMREAD_UNCHANGED)
            f, p, fa, nr = segmentation_score(s["regions"], bid)
            seg = [seg[0] + f, seg[1] + p, seg[2] + fa, seg[3] + nr]
        if not a.no_baseline:
            depth = cv2.imread(os.path.join(d, "depth.tif"), cv2.IMREAD_UNCHANGED)
            photo = cv2.imread(os.path.join(d, "photo.png"), cv2.IMREAD_GRAYSCALE)
            du8 = normalised_depth(depth)
            for k in base:
                H, ms = baseline(k, photo, du8)
                e = corner_error(H, Ht, truth["corners"], psize)[0] if H is not None else None
                base[k].append({"found": H is not None, "error": e, "ms": ms, "success": e is not None and e <= 5.0})
        print("scene %d: %s" % (i, json.dumps({k: row.get(k) for k in ("ok", "success", "corner_error", "model")})),
              flush=True)

    neg_rows = []
    for i in range(a.negatives):
        j, err = neg_futures[i].result()
        neg_rows.append({"scene": i, "ok": bool(j and j["ok"]), "error": err, "reason": j["reason"] if j else None})
        if len(styles) > 1 or styles[0] != "classic":
            neg_rows[-1].update(style=where(i, True)[0], dir=where(i, True)[1])

    succ = [r for r in rows if r["success"]]
    wrong = [r for r in rows if r.get("ok") and not r["success"]]
    times = [r["time_ms"] for r in rows if "time_ms" in r]

    def med(key):
        v = [t[key] for t in times]
        return statistics.median(v) if v else None

    out = {
        "scenes": a.n,
        "success_rate": len(succ) / a.n,
        "wrong_registrations": len(wrong),
        "no_registration": sum(1 for r in rows if not r.get("ok")),
        "ape_px": statistics.mean(r["corner_error"] for r in succ) if succ else None,
        "time_ms_median": {k: med(k) for k in ("read", "segment_depth", "segment_photo", "match", "propagate", "query", "total")},
        "time_ms_max_total": max((t["total"] for t in times), default=None),
        "peak_rss_mb_max": max((r["peak_rss_mb"] for r in rows if "peak_rss_mb" in r), default=None),
        # what the registration itself needed, over the shared libraries resident at start
        "peak_rss_above_start_mb_max": max((r["peak_rss_above_start_mb"] for r in rows
                                            if r.get("peak_rss_above_start_mb") is not None), default=None),
        "depth_segmentation": {"buildings_found": seg[0], "buildings": seg[1], "false_regions": seg[2], "regions": seg[3]},
        "negatives": {"scenes": a.negatives, "false_registrations": sum(r["ok"] for r in neg_rows), "rows": neg_rows},
        "rows": rows,
    }
    if not a.no_baseline:
        out["baseline"] = {k: {"success_rate": sum(x["success"] for x in v) / max(1, len(v)),
                               "homography_returned": sum(x["found"] for x in v),
                               "median_ms": statistics.median(x["ms"] for x in v) if v else None} for k, v in base.items()}

    # The real tile: the truth from the georeferences.
    real = {}
    ortho, ndsm = os.path.join(a.real, "ortho_rgb_20cm.tif"), os.path.join(a.real, "ndsm_50cm.tif")
    if os.path.exists(ortho) and os.path.exists(ndsm) and not a.no_real:
        j, err = run_json([a.mvkp, "register", ndsm, ortho, "--json", "--draw", os.path.join(a.out, "montpellier.png")] + xargs)
        # photo px (0.2 m, UL 770549.8 / 6277600.2) -> depth px (0.5 m, UL 770549.75 / 6277600.25), pixel centres
        # at integer coordinates: X = x0p + (u + 0.5) * 0.2, u_d = (X - x0d) / 0.5 - 0.5.
        Ht = np.array([[0.4, 0, (770549.8 - 770549.75 + 0.1) / 0.5 - 0.5],
                       [0, 0.4, (6277600.25 - 6277600.2 + 0.1) / 0.5 - 0.5],
                       [0, 0, 1.0]])
        real = {"ok": bool(j and j["ok"]), "reason": j["reason"] if j else err,
                "time_ms": j["time_ms"] if j else None, "regions": j["regions"] if j else None}
        if j and j["ok"]:
            He = h_of(j["homography"])
            g = np.array([[u, v] for u in range(0, 252, 25) for v in range(0, 252, 25)], np.float64)
            real["mean_error_vs_georeference_px"] = float(np.linalg.norm(apply(He, g) - apply(Ht, g), axis=1).mean())
            real["note"] = "the photo is not a true ortho: roofs lean ~1.2 m E, 1.4 m S (~3.7 depth px)"
    out["real_tile"] = real

    brief = {k: v for k, v in out.items() if k != "rows"}
    print(json.dumps(brief, indent=1))
    print_tables(rows, out)
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
