#!/usr/bin/python3
"""gallery_score.py: scores multi-target recognisers on make-gallery.py frames.

  gallery_score.py --gt SET/ground_truth.json --run NAME=RESULTS.jsonl [--run ...]
                   [--max-error 10] [--json SUMMARY.json] [--md SUMMARY.md]

RESULTS.jsonl: one JSON object per frame as `mvkp recognize --json` prints
(query, found [{id, homography}], time_ms {total}); `query` is the frame path
as listed in SET/frames.txt (relative to SET), or any path ending in it.

A present target counts as recognised when a detection has its id AND the
detection's homography puts the target's corners (0,0),(w-1,0),(w-1,h-1),
(0,h-1) within --max-error pixels of the ground truth on average. Reported:
  recall                 recognised / present target instances
  id recall              right id found, whatever the pose
  mislocalised           right id, mean corner error >= --max-error
  wrong-id detections    ids reported on a gallery scene that are not in it
  gallery frames w/ wrong id
  no-target frames w/ detection (count and rate)
  "not there"            every reported exhibit that is not in the frame
                         (wrong ids + anything on no-target frames)
  latency                time_ms.total per frame: median, p95, mean
plus recall by target width, tilt and number of targets, per target, and
the list of misses and false detections.
"""
import argparse
import json
import os
import sys
from collections import defaultdict

import numpy as np


def load_results(path):
    out = {}
    with open(path) as fh:
        for line in fh:
            line = line.strip()
            if not line.startswith("{"):
                continue
            o = json.loads(line)
            if "query" in o:
                out[os.path.normpath(o["query"])] = o
    return out


def lookup(res, f):
    k = os.path.normpath(f)
    if k in res:
        return res[k]
    for q, o in res.items():
        if q.endswith(os.sep + k):
            return o
    return None


def corner_error(H, Hgt, w, h):
    src = np.float64([[0, 0, 1], [w - 1, 0, 1], [w - 1, h - 1, 1], [0, h - 1, 1]])

    def proj(M):
        p = src @ np.asarray(M, np.float64).T
        return p[:, :2] / p[:, 2:3]

    with np.errstate(all="ignore"):
        e = np.linalg.norm(proj(H) - proj(Hgt), axis=1).mean()
    return float(e) if np.isfinite(e) else float("inf")


def pct(v, q):
    return float(np.percentile(v, q)) if len(v) else float("nan")


BINS = {
    "width_frac": [(0.0, 0.3), (0.3, 0.4), (0.4, 0.5), (0.5, 1.01)],
    "tilt_deg": [(0, 10), (10, 20), (20, 30), (30, 36)],
    "scale": [(0, 0.4), (0.4, 0.6), (0.6, 0.8), (0.8, 9)],
}


def score(gt, res, max_err):
    tinfo = gt["targets"]
    inst, fp, notarget = [], [], []
    times, missing = [], 0
    for fr in gt["frames"]:
        r = lookup(res, fr["file"])
        if r is None or "error" in r:
            missing += 1
            r = {"found": []}
        else:
            times.append(r["time_ms"]["total"])
        found = r.get("found", [])
        ids_here = {o["id"] for o in fr["objects"]}
        if fr["kind"] == "gallery":
            for o in fr["objects"]:
                t = tinfo[o["id"]]
                errs = [corner_error(d["homography"], o["H"], t["width"], t["height"]) for d in found
                        if d["id"] == o["id"]]
                e = min(errs) if errs else None
                inst.append({**{k: o[k] for k in ("id", "width_frac", "tilt_deg", "roll_deg", "scale")},
                             "frame": fr["file"], "n_in_frame": len(fr["objects"]),
                             "id_found": e is not None, "error": e,
                             "ok": e is not None and e < max_err})
            for d in found:
                if d["id"] not in ids_here:
                    fp.append({"frame": fr["file"], "id": d["id"], "inliers": d.get("inliers"),
                               "votes": d.get("votes")})
        else:
            notarget.append({"frame": fr["file"], "kind": fr["kind"],
                             "found": [{"id": d["id"], "inliers": d.get("inliers"), "votes": d.get("votes")}
                                       for d in found]})
    n = len(inst)
    ok = sum(i["ok"] for i in inst)
    idf = sum(i["id_found"] for i in inst)
    gal_frames = sum(1 for f in gt["frames"] if f["kind"] == "gallery")
    fp_frames = len({f["frame"] for f in fp})
    nt_hit = [x for x in notarget if x["found"]]
    s = {
        "instances": n, "recognised": ok, "recall": ok / n if n else float("nan"),
        "id_found": idf, "id_recall": idf / n if n else float("nan"),
        "mislocalised": idf - ok,
        "gallery_frames": gal_frames, "wrong_id_detections": len(fp), "gallery_frames_with_wrong_id": fp_frames,
        "notarget_frames": len(notarget), "notarget_frames_with_detection": len(nt_hit),
        "notarget_false_rate": len(nt_hit) / len(notarget) if notarget else float("nan"),
        "not_there_reports": len(fp) + sum(len(x["found"]) for x in notarget),
        "frames_missing_in_results": missing,
        "latency_ms": {"median": pct(times, 50), "p95": pct(times, 95), "mean": float(np.mean(times)) if times else
                       float("nan")},
        "median_corner_error_px": pct([i["error"] for i in inst if i["ok"]], 50),
    }
    by = {}
    for key, bins in BINS.items():
        rows = []
        for lo, hi in bins:
            sel = [i for i in inst if lo <= i[key] < hi]
            rows.append({"range": [lo, hi], "n": len(sel), "recognised": sum(i["ok"] for i in sel)})
        by[key] = rows
    rows = []
    for k in (1, 2, 3):
        sel = [i for i in inst if i["n_in_frame"] == k]
        rows.append({"range": [k, k], "n": len(sel), "recognised": sum(i["ok"] for i in sel)})
    by["targets_in_frame"] = rows
    per = defaultdict(lambda: [0, 0])
    for i in inst:
        per[i["id"]][0] += 1
        per[i["id"]][1] += i["ok"]
    s["by"] = by
    s["per_target"] = {k: {"n": v[0], "recognised": v[1]} for k, v in sorted(per.items())}
    s["misses"] = [i for i in inst if not i["ok"]]
    s["wrong_ids"] = fp
    s["notarget_detections"] = nt_hit
    return s


def fmt_pct(a, b):
    return f"{100.0 * a / b:.1f} % ({a}/{b})" if b else "-"


def markdown(summ, names, max_err):
    L = []
    L.append("| | " + " | ".join(names) + " |")
    L.append("|---|" + "---|" * len(names))
    row = lambda label, f: L.append(f"| {label} | " + " | ".join(f(summ[n]) for n in names) + " |")
    row(f"recall (right id, mean corner error < {max_err:g} px)", lambda s: fmt_pct(s["recognised"], s["instances"]))
    row("right id, any pose", lambda s: fmt_pct(s["id_found"], s["instances"]))
    row(f"right id, corner error >= {max_err:g} px", lambda s: str(s["mislocalised"]))
    row("wrong-id detections on gallery scenes", lambda s: str(s["wrong_id_detections"]))
    row("gallery scenes with a wrong id", lambda s: fmt_pct(s["gallery_frames_with_wrong_id"], s["gallery_frames"]))
    row("no-target frames with a detection", lambda s: fmt_pct(s["notarget_frames_with_detection"],
                                                                 s["notarget_frames"]))
    row("exhibits reported that are not there", lambda s: str(s["not_there_reports"]))
    row("median corner error of recognised (px)", lambda s: f"{s['median_corner_error_px']:.2f}")
    row("time per frame, median (ms)", lambda s: f"{s['latency_ms']['median']:.1f}")
    row("time per frame, p95 (ms)", lambda s: f"{s['latency_ms']['p95']:.1f}")
    L.append("")
    titles = {"width_frac": "target width / frame width", "tilt_deg": "tilt (deg)",
              "scale": "scale (frame px per target px)", "targets_in_frame": "targets in the frame"}
    for key, title in titles.items():
        L.append(f"| recall by {title} | n | " + " | ".join(names) + " |")
        L.append("|---|---|" + "---|" * len(names))
        for j, b in enumerate(summ[names[0]]["by"][key]):
            lo, hi = b["range"]
            lab = f"{lo}" if key == "targets_in_frame" else f"{lo:g} - {min(hi, 1.0) if key == 'width_frac' else hi:g}"
            if key == "scale" and hi > 5:
                lab = f">= {lo:g}"
            L.append(f"| {lab} | {b['n']} | " + " | ".join(
                f"{100.0 * summ[n]['by'][key][j]['recognised'] / b['n']:.1f} %" if b["n"] else "-" for n in names) + " |")
        L.append("")
    L.append("| recall per target | n | " + " | ".join(names) + " |")
    L.append("|---|---|" + "---|" * len(names))
    for t, v in summ[names[0]]["per_target"].items():
        L.append(f"| {t} | {v['n']} | " + " | ".join(
            f"{summ[n]['per_target'][t]['recognised']}" for n in names) + " |")
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gt", required=True)
    ap.add_argument("--run", action="append", required=True, help="NAME=RESULTS.jsonl")
    ap.add_argument("--max-error", type=float, default=10.0)
    ap.add_argument("--json")
    ap.add_argument("--md")
    a = ap.parse_args()
    gt = json.load(open(a.gt))
    summ, names = {}, []
    for r in a.run:
        name, path = r.split("=", 1)
        names.append(name)
        summ[name] = score(gt, load_results(path), a.max_error)
    md = markdown(summ, names, a.max_error)
    print(md)
    for n in names:
        s = summ[n]
        if s["frames_missing_in_results"]:
            print(f"WARNING {n}: {s['frames_missing_in_results']} frames missing or failed in the results",
                  file=sys.stderr)
        print(f"{n}: misses:")
        for m in s["misses"][:60]:
            err = "not found" if m["error"] is None else f"error {m['error']:.1f} px"
            print(f"  {m['frame']} {m['id']}: {err} (width {m['width_frac']:.2f}, tilt {m['tilt_deg']:.0f}, "
                  f"roll {m['roll_deg']:.0f}, scale {m['scale']:.2f})")
        for w in s["wrong_ids"]:
            print(f"  WRONG ID {w['frame']}: {w['id']} ({w['inliers']} inliers / {w['votes']} votes)")
        for x in s["notarget_detections"]:
            print(f"  NO-TARGET {x['frame']} ({x['kind']}): " + ", ".join(
                f"{d['id']} ({d['inliers']}/{d['votes']})" for d in x["found"]))
    out = {"max_error_px": a.max_error, "runs": summ,
           "frames": len(gt["frames"]), "targets": len(gt["targets"]), "seed": gt.get("seed")}
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    if a.md:
        with open(a.md, "w") as fh:
            fh.write(md)


if __name__ == "__main__":
    main()
