#!/usr/bin/python3
"""Per-target accuracy of `mvkp eval --json` runs (stdlib only).

    rifs_summary.py RUN.json...   prints, per run and target: views, success
    rate (corner error < 5 px) and average corner error (failures count as
    CAP px, the thesis's "average error" needs a number for a lost target).
Imported by plot_rifs.py.
"""
import json
import sys

CAP = 50.0  # px charged for a view where the target was not found (or err > CAP)


def per_target(path, method="mvkp"):
    rows = json.load(open(path))["rows"]
    out = {}
    for r in rows:
        if r["method"] != method:
            continue
        e = r["corner_err"]
        e = CAP if e is None else min(float(e), CAP)
        t = out.setdefault(r["set"], {"n": 0, "ok": 0, "err": 0.0})
        t["n"] += 1
        t["ok"] += e < 5.0
        t["err"] += e
    return {k: {"views": v["n"], "success": v["ok"] / v["n"], "avg_err": v["err"] / v["n"]} for k, v in sorted(out.items())}


def main(argv):
    for p in argv[1:]:
        print(p)
        for k, v in per_target(p).items():
            print(f"  {k:24s} views {v['views']:4d}  success {v['success']:.3f}  avg err {v['avg_err']:6.2f} px")


if __name__ == "__main__":
    main(sys.argv)
