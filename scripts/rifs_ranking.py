#!/usr/bin/python3
"""Offline comparison of view-track rankings (RIFS variants) from the output of
build/mvkp_rifs_analysis. For a ranking and a budget K, a view counts as
recoverable when the top-K tracks hold at least MIN correct matches in it (a
proxy for the detection rate of a model built from those K tracks).

    rifs_ranking.py PREFIX [K ...]
"""
import collections
import csv
import math
import sys

MIN = 10
N_V = 122  # 50 general + 72 rotation views (the thesis's setting)
L_SS = max(3, N_V // 20)


def load(prefix):
    tracks = collections.defaultdict(list)
    for r in csv.DictReader(open(prefix + ".tracks.csv")):
        tracks[r["target"]].append({k: (float(v) if k != "target" else v) for k, v in r.items()})
    hits = collections.defaultdict(lambda: collections.defaultdict(list))
    for r in csv.DictReader(open(prefix + ".hits.csv")):
        hits[r["target"]][int(r["view"])].append((float(r["x"]), float(r["y"]), int(r["correct"]), int(r["wrong"])))
    return tracks, hits


def frs(t, alpha, ds, vs, lo, hi, rescale):
    rrs = t[ds] / max(t[vs], 1e-12)
    if rescale == "log":
        rrs = math.log(rrs)
    r = L_SS + (rrs - lo) * (N_V - L_SS) / (hi - lo) if hi > lo else 0.5 * (L_SS + N_V)
    return alpha * r + (1 - alpha) * t["ss"]


def rankings(ts):
    out = {"SS (alpha 0)": [t["ss"] for t in ts], "general SS": [t["general"] for t in ts]}
    for var in ("all", "gen", "rot"):
        ds, vs = "ds_" + var, "vs_" + var
        for rescale in ("linear", "log", "rank"):
            rr = [t[ds] / max(t[vs], 1e-12) for t in ts]
            if rescale == "log":
                rr = [math.log(x) for x in rr]
            if rescale == "rank":
                order = sorted(range(len(rr)), key=lambda i: rr[i])
                rk = [0] * len(rr)
                for p, i in enumerate(order):
                    rk[i] = p / max(1, len(rr) - 1)
                rr = rk
            lo, hi = min(rr), max(rr)
            for alpha in (0.25, 0.5):
                out[f"FRS a={alpha} stats={var} {rescale}"] = [
                    alpha * (L_SS + (r - lo) * (N_V - L_SS) / (hi - lo)) + (1 - alpha) * t["ss"] for r, t in zip(rr, ts)]
    return out


def main(prefix, budgets):
    tracks, hits = load(prefix)
    table = collections.defaultdict(dict)
    for target, ts in tracks.items():
        # Correct matches per view per track (hits joined to the nearest track).
        per_view = []
        for v, hs in hits[target].items():
            c = collections.Counter()
            for x, y, ok, bad in hs:
                j = min(range(len(ts)), key=lambda i: (ts[i]["x"] - x) ** 2 + (ts[i]["y"] - y) ** 2)
                if (ts[j]["x"] - x) ** 2 + (ts[j]["y"] - y) ** 2 <= 9:
                    c[j] += ok
            per_view.append(c)
        for name, score in rankings(ts).items():
            order = sorted(range(len(ts)), key=lambda i: -score[i])
            for K in budgets:
                k = int(K[:-1]) * len(ts) // 100 if K.endswith("%") else int(K)
                top = set(order[:k])
                ok = sum(1 for c in per_view if sum(n for j, n in c.items() if j in top) >= MIN)
                hitsum = sum(sum(n for j, n in c.items() if j in top) for c in per_view)
                table[(name, K)][target] = (ok / max(1, len(per_view)), hitsum)
    targets = sorted(tracks)
    for K in budgets:
        base = table[("SS (alpha 0)", K)]
        print(f"\n== budget {K}: recoverable views (>= {MIN} correct matches in the top-K tracks), mean over {len(targets)} targets")
        rows = []
        for (name, k), d in table.items():
            if k != K:
                continue
            mean = sum(d[t][0] for t in targets) / len(targets)
            wins = sum(1 for t in targets if d[t][0] > base[t][0])
            losses = sum(1 for t in targets if d[t][0] < base[t][0])
            hwins = sum(1 for t in targets if d[t][1] > base[t][1])
            rows.append((mean, name, wins, losses, hwins))
        for mean, name, w, l, hw in sorted(rows, reverse=True):
            print(f"  {mean:.3f}  {name:34s} vs SS: better on {w:2d}, worse on {l:2d}; more correct matches on {hw:2d}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:] or ["50", "30%"])
