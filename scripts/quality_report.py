#!/usr/bin/python3
"""quality_report.py OUT_DIR IMAGES_DIR: the tables of scripts/quality-validation.sh
(stdlib only). Spearman uses average ranks for ties."""
import csv
import glob
import json
import os
import sys


def ranks(x):
    order = sorted(range(len(x)), key=lambda i: x[i])
    r = [0.0] * len(x)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and x[order[j + 1]] == x[order[i]]:
            j += 1
        for k in range(i, j + 1):
            r[order[k]] = (i + j) / 2.0 + 1
        i = j + 1
    return r


def pearson(a, b):
    n = len(a)
    ma, mb = sum(a) / n, sum(b) / n
    sa = sum((x - ma) ** 2 for x in a) ** 0.5
    sb = sum((y - mb) ** 2 for y in b) ** 0.5
    return sum((x - ma) * (y - mb) for x, y in zip(a, b)) / (sa * sb) if sa and sb else float("nan")


def spearman(a, b):
    return pearson(ranks(a), ranks(b))


def measured_rate(path):
    d = json.load(open(path))
    if d.get("untrainable"):
        return 0.0
    rows = [r for r in d["rows"] if r["method"] == "mvkp"]
    ok = sum(1 for r in rows if r["corner_err"] is not None and r["corner_err"] < 5)
    return ok / len(rows)


def main(out, images):
    cat = {}
    with open(os.path.join(images, "images.csv")) as f:
        for row in csv.DictReader(f):
            cat[os.path.splitext(row["file"])[0]] = row["category"]
    table = []
    for j in sorted(glob.glob(os.path.join(out, "score", "*-orig.json"))):
        name = os.path.basename(j)[: -len("-orig.json")]
        s = json.load(open(j))
        if "score" not in s:
            continue
        edits = {}
        for e in glob.glob(os.path.join(out, "score", name + "-*.json")):
            tag = os.path.basename(e)[len(name) + 1: -len(".json")]
            if tag != "orig":
                d = json.load(open(e))
                if "score" in d:
                    edits[tag] = d["score"]
        photo = [abs(v - s["score"]) for k, v in edits.items() if not k.startswith("resize")]
        size = [abs(v - s["score"]) for k, v in edits.items() if k.startswith("resize")]
        table.append({
            "image": name, "category": cat.get(name, "?"), "score": s["score"],
            "expected_rate": s.get("expected_detection_rate", 0.0),
            "measured_rate": measured_rate(os.path.join(out, "synth", name + ".json")),
            "max_delta_photometric": max(photo) if photo else None,
            "max_delta_resize": max(size) if size else None,
            "edits": edits, "wall_s": s.get("wall_s"), "time_ms": s.get("time_ms"),
            "reasons": [r["code"] for r in s.get("reasons", [])],
        })
    if not table:
        sys.exit("no scores found under " + out)
    sc = [t["score"] for t in table]
    mr = [t["measured_rate"] for t in table]
    er = [t["expected_rate"] for t in table]
    rho = spearman(sc, mr)
    rho_exp = spearman(er, mr)
    lines = ["| image | category | score | expected rate | measured rate | max Δ photometric | max Δ resize | s | reasons |",
             "|---|---|---|---|---|---|---|---|---|"]
    for t in sorted(table, key=lambda t: -t["score"]):
        f = lambda v: "-" if v is None else str(v)
        lines.append(f"| {t['image']} | {t['category']} | {t['score']} | {t['expected_rate']:.2f} | {t['measured_rate']:.2f} | "
                     f"{f(t['max_delta_photometric'])} | {f(t['max_delta_resize'])} | {t['wall_s']:.2f} | {', '.join(t['reasons'])} |")
    photo = [t["max_delta_photometric"] for t in table if t["max_delta_photometric"] is not None]
    size = [t["max_delta_resize"] for t in table if t["max_delta_resize"] is not None]
    walls = [t["wall_s"] for t in table if t["wall_s"] is not None]
    cats = sorted(set(t["category"] for t in table))
    counts = ", ".join("%s %d" % (c, sum(1 for t in table if t["category"] == c)) for c in cats)
    summary = [
        f"images: {len(table)} ({counts})",
        f"Spearman(score, measured detection rate) = {rho:.3f}   (goal >= 0.7)",
        f"Spearman(expected rate, measured rate)   = {rho_exp:.3f}",
        f"max |score change|, photometric edits (gain, gamma, brightness): {max(photo) if photo else '-'} points "
        f"(goal <= 10; images over 10: {sum(1 for v in photo if v > 10)})",
        f"max |score change|, resize 0.5x..2x: {max(size) if size else '-'} points "
        f"(goal <= 10; images over 10: {sum(1 for v in size if v > 10)})",
        f"wall time per image (mvkp quality, incl. start-up): max {max(walls):.2f} s, median {sorted(walls)[len(walls) // 2]:.2f} s (goal <= 3 s)",
    ]
    report = "\n".join(["# mvkp quality validation", ""] + [f"- {s}" for s in summary] + [""] + lines) + "\n"
    open(os.path.join(out, "quality-report.md"), "w").write(report)
    json.dump({"spearman": rho, "spearman_expected": rho_exp, "rows": table}, open(os.path.join(out, "quality.json"), "w"), indent=1)
    print(report)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else os.path.join(sys.argv[1], "images"))
