#!/usr/bin/python3
"""Merges the runs of bench/run_knn_suite.sh into OUTDIR/knn_suite.json and
prints one combined table. Python 3 standard library only.

    knn_suite.py OUTDIR [--sizes "4000 50000"] [--descriptors "wh sift64 sift128"]
                        [--command CMD] [--generation-seconds S] [--run-seconds S]
    knn_suite.py --table OUTDIR/knn_suite.json     (print the table of a merged file)
"""
import argparse
import datetime
import json
import os
import platform
import sys

DESCRIPTORS = {
    "wh": "WH 20-D (mvkp ExtractFeatures)",
    "sift64": "SIFT-PCA 64-D (OpenCV SIFT, PCA 128->64)",
    "sift128": "SIFT 128-D (OpenCV SIFT)",
}


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def read_text(path):
    try:
        with open(path) as f:
            return f.read().strip()
    except OSError:
        return None


def merge(args):
    out = os.path.abspath(args.outdir)
    runs = []
    for n in [int(s) for s in args.sizes.split()]:
        for d in args.descriptors.split():
            base = os.path.join(out, "runs", "%s-%d" % (d, n))
            if not os.path.exists(base + ".json"):
                print("missing %s.json, skipped" % base, file=sys.stderr)
                continue
            with open(base + ".json") as f:
                result = json.load(f)
            wall = read_text(base + ".time")
            runs.append({
                "descriptor": d,
                "descriptor_name": DESCRIPTORS.get(d, d),
                "n": n,
                "generated": read_text(os.path.join(out, "data", "%s-%d.txt" % (d, n))),
                "wall_seconds": float(wall) if wall else None,
                "result": result,
            })
    images = read_text(os.path.join(out, "images", "images.txt"))
    suite = {
        "command": args.command,
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "host": {"cpu": cpu_model(), "cores": os.cpu_count(), "kernel": platform.release()},
        "k": runs[0]["result"]["data"]["k"] if runs else None,
        "threads": 1,
        "images": images.splitlines() if images else [],
        "generation_seconds": args.generation_seconds,
        "run_seconds": args.run_seconds,
        "runs": runs,
    }
    with open(os.path.join(out, "knn_suite.json"), "w") as f:
        json.dump(suite, f, indent=1)
    return suite


def fmt(v, nd, width):
    if v is None:
        return "-".rjust(width)
    return ("%.*f" % (nd, v)).rjust(width)


def fmt_count(v, width):
    if v is None:
        return "-".rjust(width)
    return ("%.0f" % v if v >= 100 else "%.1f" % v).rjust(width)


def recall_str(m):
    s, b = m["recall_at_1_single"], m.get("recall_at_1_batch")
    r = "%.4f" % s
    if b is not None and abs(b - s) > 1e-12:
        r += "/%.4f" % b
    return r


def table(suite, file=sys.stdout):
    p = lambda *a: print(*a, file=file)
    p("kNN suite: %s" % (suite.get("command") or ""))
    p("%s, %s cores; k=%s, single thread; %s" % (suite["host"]["cpu"], suite["host"]["cores"], suite.get("k"),
                                                suite.get("date")))
    if suite["runs"]:
        for e in suite["runs"][0]["result"].get("environment", []):
            p(e)
    p("us/q 1: median of one query per call, mean 1: their mean; us/q B: batched, total/nq (a mean); dist/q: exact "
      "distance computations per query (mean, single-query pass); %n = dist/q / n; mem/raw: structure bytes / raw vector "
      "bytes (goal in the dataset line)")
    by_desc = {}
    for r in suite["runs"]:
        by_desc.setdefault(r["descriptor"], []).append(r)
    header = "%9s %-16s %9s %9s %9s %9s %15s %8s %10s %7s" % ("n", "method", "build s", "us/q 1", "mean 1", "us/q B",
                                                              "recall@1", "mem/raw", "dist/q", "%n")
    for d, runs in by_desc.items():
        res0 = runs[0]["result"]
        goal = res0.get("memory_goal", {})
        p("")
        p("== %s, dim %d; memory goal mem/raw <= %s" % (runs[0]["descriptor_name"], res0["data"]["dim"],
                                                        fmt(goal.get("mem_over_raw"), 3, 0)))
        p(header)
        for r in runs:
            data = r["result"]["data"]
            for m in r["result"]["methods"]:
                if "error" in m:
                    p("%9d %-16s FAILED: %s" % (data["n"], m["name"], m["error"]))
                    continue
                dq = m.get("distance_computations_per_query")
                pct = None if dq is None else 100.0 * dq / data["n"]
                p("%9d %-16s %9s %9s %9s %9s %15s %8s %10s %7s" % (
                    data["n"], m["name"], fmt(m["build_ms"] / 1000, 2, 0), fmt(m["us_per_query_single_median"], 1, 0),
                    fmt(m.get("us_per_query_single_mean"), 1, 0), fmt(m["us_per_query_batch"], 1, 0), recall_str(m), fmt(m.get("mem_over_raw"), 3, 0),
                    fmt_count(dq, 0), "-" if pct is None else ("%.3g" % pct)))
            p("%9s (nq=%d, single-query passes %s, run wall %s s)" % (
                "", data["nq"], r["result"].get("repeat", "?"),
                "?" if r["wall_seconds"] is None else "%.0f" % r["wall_seconds"]))
    g, rs = suite.get("generation_seconds"), suite.get("run_seconds")
    if g is not None and rs is not None:
        p("")
        p("suite wall time %.0f s: images and datasets %.0f s (~0 when cached in OUTDIR), runs %.0f s" % (g + rs, g, rs))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("outdir", help="suite OUTDIR, or with --table a merged knn_suite.json")
    ap.add_argument("--table", action="store_true", help="only print the table of a merged knn_suite.json")
    ap.add_argument("--sizes", default="4000 50000 1000000")
    ap.add_argument("--descriptors", default="wh sift64 sift128")
    ap.add_argument("--command", default=None)
    ap.add_argument("--generation-seconds", type=float, default=None)
    ap.add_argument("--run-seconds", type=float, default=None)
    args = ap.parse_args()
    if args.table:
        with open(args.outdir) as f:
            suite = json.load(f)
    else:
        suite = merge(args)
    table(suite)


if __name__ == "__main__":
    main()
