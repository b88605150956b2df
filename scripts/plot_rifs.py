#!/usr/bin/python3
"""Plots and summarises the RIFS experiments (scripts/rifs-experiments.sh), stdlib only.

    plot_rifs.py OUT_DIR

Reads OUT_DIR/runs/*.json (`mvkp eval --json` output) named
keep30p-alpha{A}-seed{S}.json and keep50-alpha{A}-seed{S}.json (any keep
label of the form keepX works). Per target and setting (keep, alpha) the
seeds are pooled: success rate and average corner error are the means over
the seeds present (rifs_summary.per_target: success = error < 5 px, a lost
target or an error above CAP px counts as CAP px). Writes

  OUT_DIR/fig3_16.svg          Fig. 3.16: average error per target, alpha 0.5
                               vs alpha 0, keep 30 %, targets ordered by
                               increasing alpha = 0.5 error
  OUT_DIR/fig3_16_success.svg  the same for the success rate
  OUT_DIR/fig3_18.svg          Fig. 3.18: mean error (and mean success) over
                               all targets against alpha, keep 30 %
  OUT_DIR/rifs-report.md       tables (also printed to stdout)

Settings that are missing are skipped; incomplete runs (seeds or alphas
missing) are reported as they are.
"""
import glob
import json
import math
import os
import re
import statistics
import sys
from xml.sax.saxutils import escape

_here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, _here)
sys.path.insert(0, os.path.join(_here, "..", "bench"))
import rifs_summary  # noqa: E402
from plot_knn import marker  # noqa: E402  (one SVG marker helper for both plot scripts)

CAP = rifs_summary.CAP
OK_PX = 5.0  # success threshold used by rifs_summary.per_target
MAIN_KEEP = "keep30p"
NAME_RE = re.compile(r"^(keep[^-]+)-alpha([0-9]*\.?[0-9]+)-seed([0-9]+)\.json$")
EPS = 1e-9

# Plot style, after bench/plot_knn.py.
FONT = "font-family='DejaVu Sans, Arial, Helvetica, sans-serif'"
MARGIN_L, MARGIN_R, MARGIN_T, MARGIN_B = 70, 20, 46, 50
C_A0 = ("#1f77b4", "circle")     # alpha = 0
C_A05 = ("#d62728", "square")    # alpha = 0.5
C_SWEEP = ("#2ca02c", "diamond")
C_MEDIAN = ("#ff7f0e", "triangle")


# ---------------------------------------------------------------- data

def keep_label(keep):
    """keep30p -> 'keep 30 %', keep50 -> 'keep 50'."""
    m = re.match(r"^keep([0-9.]+)(p?)$", keep)
    if not m:
        return keep
    return "keep %s %%" % m.group(1) if m.group(2) else "keep %s" % m.group(1)


def alpha_str(a):
    return "%g" % a


def view_errors(path, method="mvkp"):
    """{target: [capped corner error per view]} (the medians need the views)."""
    out = {}
    for r in json.load(open(path))["rows"]:
        if r["method"] != method:
            continue
        e = r["corner_err"]
        out.setdefault(r["set"], []).append(CAP if e is None else min(float(e), CAP))
    return out


def load_runs(runs_dir):
    """{(keep, alpha): {seed: {"path", "pt": per_target, "errs": view_errors}}}."""
    files = sorted(glob.glob(os.path.join(runs_dir, "*.json")))
    runs, skipped = {}, []
    for p in files:
        m = NAME_RE.match(os.path.basename(p))
        if not m:
            skipped.append((p, "name not keepX-alphaA-seedS.json"))
            continue
        keep, alpha, seed = m.group(1), float(m.group(2)), int(m.group(3))
        try:
            pt = rifs_summary.per_target(p)
            errs = view_errors(p)
        except (OSError, ValueError, KeyError, TypeError) as e:
            skipped.append((p, "unreadable: %s" % e))
            continue
        if not pt:
            skipped.append((p, "no mvkp rows"))
            continue
        runs.setdefault((keep, alpha), {})[seed] = {"path": p, "pt": pt, "errs": errs}
    return runs, skipped


def pool(seed_runs):
    """Per target, means over the seeds that have it:
    {target: {"success", "avg_err", "median_err", "views", "seeds"}}."""
    acc = {}
    for seed, run in sorted(seed_runs.items()):
        for t, v in run["pt"].items():
            a = acc.setdefault(t, {"success": [], "avg_err": [], "median_err": [], "views": 0, "seeds": []})
            a["success"].append(v["success"])
            a["avg_err"].append(v["avg_err"])
            a["median_err"].append(statistics.median(run["errs"][t]))
            a["views"] += v["views"]
            a["seeds"].append(seed)
    return {t: {"success": statistics.mean(a["success"]), "avg_err": statistics.mean(a["avg_err"]),
                "median_err": statistics.mean(a["median_err"]), "views": a["views"], "seeds": a["seeds"]}
            for t, a in sorted(acc.items())}


def pooled_views(seed_runs, targets=None):
    """All views of all (chosen) targets and seeds: (n, success, avg err, median err)."""
    errs = [e for run in seed_runs.values() for t, es in run["errs"].items()
            if targets is None or t in targets for e in es]
    if not errs:
        return 0, float("nan"), float("nan"), float("nan")
    return (len(errs), sum(e < OK_PX for e in errs) / len(errs), statistics.mean(errs), statistics.median(errs))


def winner(s0, s5, e0, e5):
    """Partition of the (alpha 0, alpha 0.5) comparison of one target."""
    succ_better = s5 > s0 + EPS
    err_better = e5 < e0 - EPS
    if succ_better and err_better:
        return "α=0.5 better on both"
    if succ_better:
        return "α=0.5 better on success only"
    if err_better:
        return "α=0.5 better on error only"
    if abs(s5 - s0) <= EPS and abs(e5 - e0) <= EPS:
        return "tie"
    return "α=0 better"


# ---------------------------------------------------------------- SVG

def nice_ticks(lo, hi, n=6):
    span = hi - lo
    if span <= 0:
        return [lo]
    raw = span / n
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    t = math.ceil(lo / step - 1e-9) * step
    ticks = []
    while t <= hi + 1e-9 * step:
        ticks.append(round(t, 10))
        t += step
    return ticks


def svg_open(width, height, title, subtitle):
    svg = ["<svg xmlns='http://www.w3.org/2000/svg' width='%d' height='%d' viewBox='0 0 %d %d'>" %
           (width, height, width, height),
           "<rect width='100%' height='100%' fill='white'/>",
           "<text x='12' y='22' font-size='15' font-weight='bold' %s>%s</text>" % (FONT, escape(title))]
    if subtitle:
        svg.append("<text x='12' y='42' font-size='11' fill='#444' %s>%s</text>" % (FONT, escape(subtitle)))
    return svg


def svg_write(svg, path):
    svg.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(svg) + "\n")


def panel(svg, x0, y0, w, h, title, xlabel, ylabel, series, xrange, xticks, yrange, yfmt="%g", whiskers=None):
    """Linear axes. series: [(name, colour, shape, dashed, [(x, y, tooltip), ...])].
    xticks: [(x, label)]. whiskers: {name: {x: (lo, hi)}} drawn as vertical bars."""
    px0, py0 = x0 + MARGIN_L, y0 + MARGIN_T
    pw, ph = w - MARGIN_L - MARGIN_R, h - MARGIN_T - MARGIN_B
    svg.append("<text x='%.1f' y='%.1f' font-size='13' font-weight='bold' text-anchor='middle' %s>%s</text>" %
               (px0 + pw / 2, y0 + 18, FONT, escape(title)))
    svg.append("<rect x='%d' y='%d' width='%d' height='%d' fill='white' stroke='#444'/>" % (px0, py0, pw, ph))
    if not any(pts for *_, pts in series):
        svg.append("<text x='%.1f' y='%.1f' font-size='12' text-anchor='middle' fill='#666' %s>no data</text>" %
                   (px0 + pw / 2, py0 + ph / 2, FONT))
        return
    xlo, xhi = xrange
    ylo, yhi = yrange
    X = lambda v: px0 + (v - xlo) / (xhi - xlo) * pw
    Y = lambda v: py0 + ph - (v - ylo) / (yhi - ylo) * ph
    for t in nice_ticks(ylo, yhi):
        svg.append("<line x1='%d' y1='%.1f' x2='%d' y2='%.1f' stroke='#ddd' stroke-width='1'/>" %
                   (px0, Y(t), px0 + pw, Y(t)))
        svg.append("<text x='%d' y='%.1f' font-size='11' text-anchor='end' %s>%s</text>" %
                   (px0 - 5, Y(t) + 4, FONT, yfmt % t))
    for xv, label in xticks:
        svg.append("<line x1='%.1f' y1='%d' x2='%.1f' y2='%d' stroke='#eee'/>" % (X(xv), py0, X(xv), py0 + ph))
        svg.append("<text x='%.1f' y='%d' font-size='11' text-anchor='middle' %s>%s</text>" %
                   (X(xv), py0 + ph + 15, FONT, escape(label)))
    svg.append("<text x='%.1f' y='%d' font-size='11' text-anchor='middle' %s>%s</text>" %
               (px0 + pw / 2, py0 + ph + 34, FONT, escape(xlabel)))
    svg.append("<text transform='translate(%d,%.1f) rotate(-90)' font-size='11' text-anchor='middle' %s>%s</text>" %
               (x0 + 16, py0 + ph / 2, FONT, escape(ylabel)))
    for name, colour, shape, dashed, pts in series:
        dash = " stroke-dasharray='6,4'" if dashed else ""
        if len(pts) > 1:
            svg.append("<polyline fill='none' stroke='%s' stroke-width='2'%s points='%s'/>" %
                       (colour, dash, " ".join("%.1f,%.1f" % (X(x), Y(y)) for x, y, _ in pts)))
    for name, colour, shape, dashed, pts in series:
        for x, y, tip in pts:
            w_ = (whiskers or {}).get(name, {}).get(x)
            if w_ is not None and abs(w_[1] - w_[0]) > EPS:
                svg.append("<line x1='%.1f' y1='%.1f' x2='%.1f' y2='%.1f' stroke='%s' stroke-width='1.2'/>" %
                           (X(x), Y(w_[0]), X(x), Y(w_[1]), colour))
                for yy in w_:
                    svg.append("<line x1='%.1f' y1='%.1f' x2='%.1f' y2='%.1f' stroke='%s' stroke-width='1.5'/>" %
                               (X(x) - 4, Y(yy), X(x) + 4, Y(yy), colour))
            svg.append("<g>%s<title>%s</title></g>" % (marker(shape, X(x), Y(y), colour), escape(tip)))


def legend(svg, lx, ly, heading, entries, notes=()):
    """entries: [(name, colour, shape, dashed)]. Returns the y below it."""
    svg.append("<text x='%d' y='%d' font-size='12' font-weight='bold' %s>%s</text>" % (lx, ly - 8, FONT, heading))
    y = ly
    for name, colour, shape, dashed in entries:
        y += 10
        dash = " stroke-dasharray='6,4'" if dashed else ""
        svg.append("<line x1='%d' y1='%d' x2='%d' y2='%d' stroke='%s' stroke-width='2'%s/>" %
                   (lx, y, lx + 34, y, colour, dash))
        svg.append(marker(shape, lx + 17, y, colour))
        svg.append("<text x='%d' y='%d' font-size='12' %s>%s</text>" % (lx + 42, y + 4, FONT, escape(name)))
        y += 12
    y += 14
    for t in notes:
        svg.append("<text x='%d' y='%d' font-size='11' fill='#444' %s>%s</text>" % (lx, y, FONT, escape(t)))
        y += 15
    return y


def index_key(svg, lx, ly, order, ncols=2, colw=120):
    """Test index -> target name, in columns."""
    svg.append("<text x='%d' y='%d' font-size='12' font-weight='bold' %s>test index</text>" % (lx, ly, FONT))
    rows = (len(order) + ncols - 1) // ncols
    for i, t in enumerate(order):
        c, r = divmod(i, rows)
        svg.append("<text x='%d' y='%d' font-size='11' fill='#333' %s>%2d  %s</text>" %
                   (lx + c * colw, ly + 16 + 14 * r, FONT, i + 1, escape(t)))
    return ly + 16 + 14 * rows


def plot_per_target(path, metric, order, p0, p5, label, seeds_note):
    """Fig. 3.16 (metric avg_err) or its success companion."""
    n = len(order)
    pw = max(480, 30 * n + MARGIN_L + MARGIN_R)
    ph = 330
    legend_w = 270
    width, height = pw + legend_w + 20, 60 + ph + 20
    if metric == "avg_err":
        title = "RIFS: average error per target, top 30 % of view tracks"
        ylabel, unit, yfmt = "average corner error (px)", "px", "%g"
        vals = [p[t][metric] for p in (p0, p5) for t in order]
        yrange = (0.0, max(1.0, max(vals)) * 1.08)
        get = lambda p, t: p[t]["avg_err"]
    else:
        title = "RIFS: success rate per target, top 30 % of view tracks"
        ylabel, unit, yfmt = "success rate (%, corner error < 5 px)", "%", "%g"
        yrange = (0.0, 105.0)
        get = lambda p, t: 100.0 * p[t]["success"]
    if label != keep_label(MAIN_KEEP):
        title = title.replace("top 30 % of view tracks", label)
    svg = svg_open(width, height, title, "targets ordered by increasing α = 0.5 average error; " + seeds_note)
    series = []
    for name, (colour, shape), p in (("α = 0.5", C_A05, p5), ("α = 0", C_A0, p0)):
        pts = [(i + 1, get(p, t), "%s  #%d %s: %.3g %s" % (name, i + 1, t, get(p, t), unit)) for i, t in enumerate(order)]
        series.append((name, colour, shape, False, pts))
    step = 1 if n <= 30 else 5
    xticks = [(i, str(i)) for i in range(1, n + 1) if i == 1 or i % step == 0]
    panel(svg, 0, 60, pw, ph, "%s, %d targets" % (label, n), "test index", ylabel, series,
          (0.5, n + 0.5), xticks, yrange, yfmt)
    lx = pw + 10
    y = legend(svg, lx, 60 + MARGIN_T, "setting", [(s[0], s[1], s[2], False) for s in series],
               ["lost target / error > %g px = %g px" % (CAP, CAP)] if metric == "avg_err" else [])
    index_key(svg, lx, y + 6, order)
    svg_write(svg, path)


def plot_sweep(path, sweep, label, seeds_note):
    """Fig. 3.18: error and success over all targets against alpha."""
    pw, ph = 470, 300
    legend_w = 260
    width, height = pw + legend_w + 20, 60 + 2 * ph + 20 + 20
    svg = svg_open(width, height, "RIFS: average error and success rate over all targets vs α (%s)" % label,
                   seeds_note)
    alphas = [r["alpha"] for r in sweep]
    xr = (min(alphas + [0.0]) - 0.05, max(alphas + [1.0]) + 0.05)
    xticks = [(a / 10, "%g" % (a / 10)) for a in range(0, 11)]
    err = [(r["alpha"], r["avg_err"], "α=%g: mean avg err %.3g px (%d targets)" % (r["alpha"], r["avg_err"], r["n"]))
           for r in sweep]
    med = [(r["alpha"], r["median_err"], "α=%g: mean median err %.3g px" % (r["alpha"], r["median_err"]))
           for r in sweep]
    suc = [(r["alpha"], 100 * r["success"], "α=%g: mean success %.1f %%" % (r["alpha"], 100 * r["success"]))
           for r in sweep]
    ws_err = {"mean average error": {r["alpha"]: r["err_range"] for r in sweep if r["err_range"]}}
    ws_suc = {"mean success rate": {r["alpha"]: tuple(100 * v for v in r["succ_range"]) for r in sweep
                                    if r["succ_range"]}}
    ymax = max([v for _, v, _ in err + med] + [1.0]) * 1.1
    s_err = [("mean average error", C_SWEEP[0], C_SWEEP[1], False, err),
             ("mean median error", C_MEDIAN[0], C_MEDIAN[1], True, med)]
    panel(svg, 0, 60, pw, ph, "error (mean over targets)", "α", "corner error (px)", s_err, xr, xticks,
          (0.0, ymax), whiskers=ws_err)
    sl = [v for _, v, _ in suc]
    lo = max(0.0, min(sl) - 10)
    hi = min(105.0, max(sl) + 10)
    s_suc = [("mean success rate", C_A0[0], C_A0[1], False, suc)]
    panel(svg, 0, 60 + ph + 20, pw, ph, "success rate (mean over targets)", "α",
          "success rate (%, corner error < 5 px)", s_suc, xr, xticks, (lo, hi), whiskers=ws_suc)
    notes = ["per target: mean over seeds;",
             "average error: lost / > %g px = %g px;" % (CAP, CAP),
             "median error: per-target median",
             "of the views, mean over targets;",
             "bars: range of the per-seed means",
             "(only with several seeds)"]
    legend(svg, pw + 10, 60 + MARGIN_T, "curve",
           [(s[0], s[1], s[2], s[3]) for s in s_err + s_suc], notes)
    svg_write(svg, path)


# ---------------------------------------------------------------- report

def fmt_pct(v):
    return "%.1f %%" % (100 * v)


def seeds_of(runs, key):
    return sorted(runs.get(key, {}))


def compare_section(lines, runs, keep):
    """Per-target alpha 0 vs 0.5 table and counts; returns (order, p0, p5) or None."""
    k0, k5 = (keep, 0.0), (keep, 0.5)
    label = keep_label(keep)
    if k0 not in runs or k5 not in runs:
        have = [alpha_str(a) for (k, a) in sorted(runs) if k == keep]
        lines.append("## %s: α = 0 vs α = 0.5\n" % label)
        lines.append("Skipped: needs runs with α = 0 and α = 0.5 (found α: %s).\n" % (", ".join(have) or "none"))
        return None
    p0, p5 = pool(runs[k0]), pool(runs[k5])
    common = sorted(set(p0) & set(p5))
    order = sorted(common, key=lambda t: (p5[t]["avg_err"], t))
    s0, s5 = seeds_of(runs, k0), seeds_of(runs, k5)
    lines.append("## %s: α = 0 vs α = 0.5 per target\n" % label)
    para = ["Seeds pooled (mean over seeds): α = 0: %s; α = 0.5: %s." %
            (", ".join(map(str, s0)), ", ".join(map(str, s5)))]
    if s0 != s5:
        para.append("**Warning: the two settings have different seeds (incomplete run?); the comparison is"
                    " not like for like.**")
    only = sorted(set(p0) ^ set(p5))
    if only:
        para.append("Targets in only one of the settings (left out): %s." % ", ".join(only))
    para.append("Rows ordered by increasing α = 0.5 average error (= test index of fig3_16).\n")
    lines.append(" ".join(para))
    lines.append("| # | target | success α=0 | success α=0.5 | avg err α=0 (px) | avg err α=0.5 (px) | winner |")
    lines.append("|---:|---|---:|---:|---:|---:|---|")
    tally = {}
    both = ge_lower = 0
    for i, t in enumerate(order):
        a, b = p0[t], p5[t]
        w = winner(a["success"], b["success"], a["avg_err"], b["avg_err"])
        tally[w] = tally.get(w, 0) + 1
        lower = b["avg_err"] < a["avg_err"] - EPS
        both += lower and b["success"] > a["success"] + EPS
        ge_lower += lower and b["success"] >= a["success"] - EPS
        lines.append("| %d | %s | %s | %s | %.2f | %.2f | %s |" %
                     (i + 1, t, fmt_pct(a["success"]), fmt_pct(b["success"]), a["avg_err"], b["avg_err"], w))
    n = len(order)
    m0 = statistics.mean(p0[t]["avg_err"] for t in order) if n else float("nan")
    m5 = statistics.mean(p5[t]["avg_err"] for t in order) if n else float("nan")
    ms0 = statistics.mean(p0[t]["success"] for t in order) if n else float("nan")
    ms5 = statistics.mean(p5[t]["success"] for t in order) if n else float("nan")
    lines.append("| | **mean** | **%s** | **%s** | **%.2f** | **%.2f** | |" % (fmt_pct(ms0), fmt_pct(ms5), m0, m5))
    lines.append("")
    lines.append("Counts (%s, %d targets):\n" % (label, n))
    lines.append("- α = 0.5 has **higher success and lower average error** than α = 0: **%d / %d**" % (both, n))
    lines.append("- α = 0.5 has higher-or-equal success and lower average error: **%d / %d**" % (ge_lower, n))
    for w in ("α=0.5 better on both", "α=0.5 better on success only", "α=0.5 better on error only",
              "α=0 better", "tie"):
        lines.append("- %s: %d" % (w, tally.get(w, 0)))
    lines.append("")
    lines.append("(\"on success only\": higher success, error not lower; \"on error only\": lower error, success not"
                 " higher; \"α=0 better\": neither better and not both equal.)\n")
    return order, p0, p5


def sweep_rows(runs, keep):
    keys = sorted(a for (k, a) in runs if k == keep)
    if not keys:
        return [], []
    pooled = {a: pool(runs[(keep, a)]) for a in keys}
    common = set.intersection(*(set(p) for p in pooled.values()))
    dropped = sorted(set.union(*(set(p) for p in pooled.values())) - common)
    rows = []
    for a in keys:
        p = pooled[a]
        ts = sorted(common)
        if not ts:
            continue
        # Spread over seeds: mean over targets of each seed's run.
        per_seed_err, per_seed_succ = [], []
        for seed, run in runs[(keep, a)].items():
            if all(t in run["pt"] for t in ts):
                per_seed_err.append(statistics.mean(run["pt"][t]["avg_err"] for t in ts))
                per_seed_succ.append(statistics.mean(run["pt"][t]["success"] for t in ts))
        multi = len(per_seed_err) > 1
        rows.append({"alpha": a, "n": len(ts), "seeds": seeds_of(runs, (keep, a)),
                     "success": statistics.mean(p[t]["success"] for t in ts),
                     "avg_err": statistics.mean(p[t]["avg_err"] for t in ts),
                     "median_err": statistics.mean(p[t]["median_err"] for t in ts),
                     "err_range": (min(per_seed_err), max(per_seed_err)) if multi else None,
                     "succ_range": (min(per_seed_succ), max(per_seed_succ)) if multi else None})
    return rows, dropped


def report(out_dir, runs, skipped, written):
    lines = ["# RIFS experiments: %s\n" % out_dir]
    lines.append("Source: `%s` (%d run files). Success = corner error < %g px; average error counts a lost target or"
                 " an error above %g px as %g px. Per target, success and errors are means over the seeds.\n" %
                 (os.path.join(out_dir, "runs"), sum(len(v) for v in runs.values()), OK_PX, CAP, CAP))
    if skipped:
        lines.append("Skipped files:\n")
        for p, why in skipped:
            lines.append("- `%s`: %s" % (os.path.basename(p), why))
        lines.append("")
    keeps = sorted({k for k, _ in runs}, key=lambda k: (k != MAIN_KEEP, k))
    results = {}
    for keep in keeps:
        results[keep] = compare_section(lines, runs, keep)

    lines.append("## α sweep (%s)\n" % keep_label(MAIN_KEEP))
    sweep, dropped = sweep_rows(runs, MAIN_KEEP)
    if not sweep:
        lines.append("No %s runs.\n" % MAIN_KEEP)
    else:
        if dropped:
            lines.append("Targets missing from some α, left out of the means: %s.\n" % ", ".join(dropped))
        lines.append("| α | seeds | targets | mean success | mean avg err (px) | mean median-per-target err (px) |")
        lines.append("|---:|---|---:|---:|---:|---:|")
        for r in sweep:
            lines.append("| %g | %s | %d | %s | %.2f | %.2f |" % (r["alpha"], ",".join(map(str, r["seeds"])), r["n"],
                                                                  fmt_pct(r["success"]), r["avg_err"],
                                                                  r["median_err"]))
        if len({tuple(r["seeds"]) for r in sweep}) > 1:
            lines.append("\n**Warning: the α settings have different seeds (incomplete run?).**")
        lines.append("")

    lines.append("## Pooled over all views and targets: α = 0 vs α = 0.5\n")
    lines.append("All views of all seeds and of the targets present in both settings, pooled.\n")
    lines.append("| setting | α | seeds | views | success | avg err (px) | median err (px) |")
    lines.append("|---|---:|---|---:|---:|---:|---:|")
    any_pooled = False
    for keep in keeps:
        pair = [(keep, a) for a in (0.0, 0.5) if (keep, a) in runs]
        if not pair:
            continue
        common = set.intersection(*(set(pool(runs[k])) for k in pair))
        for k in pair:
            n, s, e, m = pooled_views(runs[k], common)
            any_pooled = True
            lines.append("| %s | %g | %s | %d | %s | %.2f | %.2f |" %
                         (keep_label(keep), k[1], ",".join(map(str, seeds_of(runs, k))), n, fmt_pct(s), e, m))
    if not any_pooled:
        lines.append("| (no α = 0 / 0.5 runs) | | | | | | |")
    lines.append("")

    lines.append("## Seeds and views found\n")
    lines.append("| setting | α | seeds | targets | views per target per run |")
    lines.append("|---|---:|---|---:|---|")
    all_targets = set()
    for key in sorted(runs, key=lambda k: (k[0] != MAIN_KEEP, k[0], k[1])):
        views = sorted({v["views"] for run in runs[key].values() for v in run["pt"].values()})
        targets = set(t for run in runs[key].values() for t in run["pt"])
        all_targets |= targets
        lines.append("| %s | %g | %s | %d | %s |" % (keep_label(key[0]), key[1], ",".join(map(str, seeds_of(runs, key))),
                                                    len(targets), ", ".join(map(str, views))))
    lines.append("")
    lines.append("Targets (%d): %s.\n" % (len(all_targets), ", ".join(sorted(all_targets))))
    if written:
        lines.append("Figures: %s.\n" % ", ".join("`%s`" % os.path.basename(p) for p in written))
    return "\n".join(lines), results, sweep


def main():
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        sys.exit(2)
    out_dir = sys.argv[1]
    runs_dir = os.path.join(out_dir, "runs")
    if not os.path.isdir(runs_dir):
        sys.exit("plot_rifs.py: no directory %s" % runs_dir)
    runs, skipped = load_runs(runs_dir)
    for p, why in skipped:
        print("plot_rifs.py: skipping %s: %s" % (p, why), file=sys.stderr)
    if not runs:
        sys.exit("plot_rifs.py: no usable keepX-alphaA-seedS.json runs in %s" % runs_dir)

    # First pass for the data the figures need, second for the report naming them.
    _, results, sweep = report(out_dir, runs, skipped, [])
    written = []
    res = results.get(MAIN_KEEP)
    if res and res[0]:
        order, p0, p5 = res
        note = "seeds α=0: %s, α=0.5: %s" % (",".join(map(str, seeds_of(runs, (MAIN_KEEP, 0.0)))),
                                             ",".join(map(str, seeds_of(runs, (MAIN_KEEP, 0.5)))))
        for name, metric in (("fig3_16.svg", "avg_err"), ("fig3_16_success.svg", "success")):
            path = os.path.join(out_dir, name)
            plot_per_target(path, metric, order, p0, p5, keep_label(MAIN_KEEP), note)
            written.append(path)
    else:
        print("plot_rifs.py: no %s runs with both α = 0 and α = 0.5: fig3_16 skipped" % MAIN_KEEP, file=sys.stderr)
    if sweep:
        path = os.path.join(out_dir, "fig3_18.svg")
        seeds = sorted({s for r in sweep for s in r["seeds"]})
        plot_sweep(path, sweep, keep_label(MAIN_KEEP),
                   "α = %s; seeds %s; %d targets" % (", ".join("%g" % r["alpha"] for r in sweep),
                                                     ",".join(map(str, seeds)), sweep[0]["n"]))
        written.append(path)
    else:
        print("plot_rifs.py: no %s runs: fig3_18 skipped" % MAIN_KEEP, file=sys.stderr)

    text, _, _ = report(out_dir, runs, skipped, written)
    with open(os.path.join(out_dir, "rifs-report.md"), "w") as f:
        f.write(text + "\n")
    print(text)
    for p in written + [os.path.join(out_dir, "rifs-report.md")]:
        print("wrote %s" % p, file=sys.stderr)


if __name__ == "__main__":
    main()
