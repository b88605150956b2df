#!/usr/bin/python3
"""Plots a kNN suite (bench/run_knn_suite.sh) as SVG, Python 3 standard library only.

    plot_knn.py OUTDIR/knn_suite.json [OUT.svg]     (default: knn_suite.svg next to the JSON)

One column per descriptor dimension. Top row: microseconds per query (one
query per call, median; a whisker rises to the mean where it is >= 1.25 x the
median) against database size; bottom row: exact distance
computations per query against database size (methods that report them; the
thesis's Fig. 5.3 measure). Both axes logarithmic. Solid lines: exact methods;
dashed: approximate ones. Hovering a point shows its values.
"""
import json
import math
import os
import sys
from xml.sax.saxutils import escape

# Fixed colours and markers per method so that plots of different runs compare.
STYLE = {
    "mvkp-brute-2nn": ("#1f77b4", "circle"),
    "mvkp-brute-knn": ("#6baed6", "square"),
    "mvkp-ffva-2nn": ("#d62728", "circle"),
    "mvkp-ffva-knn": ("#ff9896", "square"),
    "mvkp-ffva-approx": ("#e377c2", "diamond"),
    "faiss-flat": ("#2ca02c", "square"),
    "faiss-hnsw": ("#98df8a", "triangle"),
    "hnswlib": ("#ff7f0e", "triangle"),
    "flann-kdtree": ("#8c564b", "diamond"),
}
FALLBACK_COLOURS = ["#17becf", "#bcbd22", "#7f7f7f", "#9467bd", "#393b79"]
EXACT = {"mvkp-brute-2nn", "mvkp-brute-knn", "mvkp-ffva-2nn", "mvkp-ffva-knn", "faiss-flat"}

WHISKER_MIN_RATIO = 1.25  # mean whiskers only for heavy tails (mean >= 1.25 x median)
PANEL_W, PANEL_H = 330, 250
MARGIN_L, MARGIN_R, MARGIN_T, MARGIN_B = 70, 20, 46, 46
GAP_X, GAP_Y = 30, 40
LEGEND_W = 230
FONT = "font-family='DejaVu Sans, Arial, Helvetica, sans-serif'"


def si(v):
    """Compact label for a positive number: 4k, 50k, 1M, 0.1, 300."""
    for div, suf in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if v >= div:
            x = v / div
            return ("%g" % round(x, 2)) + suf
    return "%g" % round(v, 3)


def log_range(values, pad=0.08):
    lo, hi = math.log10(min(values)), math.log10(max(values))
    if hi - lo < 1e-9:
        lo, hi = lo - 0.5, hi + 0.5
    span = hi - lo
    return lo - pad * span, hi + pad * span


def decade_ticks(lo, hi):
    """Ticks at 1, 2, 5 x 10^k when the range is short, decades otherwise."""
    mults = (1, 2, 5) if hi - lo <= 2.5 else (1,)
    ticks = []
    for e in range(math.floor(lo) - 1, math.ceil(hi) + 1):
        for m in mults:
            t = math.log10(m) + e
            if lo <= t <= hi:
                ticks.append(t)
    return ticks


def marker(shape, x, y, colour, r=4.0):
    if shape == "square":
        return "<rect x='%.1f' y='%.1f' width='%.1f' height='%.1f' fill='%s'/>" % (x - r, y - r, 2 * r, 2 * r, colour)
    if shape == "triangle":
        pts = "%.1f,%.1f %.1f,%.1f %.1f,%.1f" % (x, y - 1.2 * r, x - r * 1.1, y + 0.8 * r, x + r * 1.1, y + 0.8 * r)
        return "<polygon points='%s' fill='%s'/>" % (pts, colour)
    if shape == "diamond":
        pts = "%.1f,%.1f %.1f,%.1f %.1f,%.1f %.1f,%.1f" % (x, y - 1.3 * r, x + r, y, x, y + 1.3 * r, x - r, y)
        return "<polygon points='%s' fill='%s'/>" % (pts, colour)
    return "<circle cx='%.1f' cy='%.1f' r='%.1f' fill='%s'/>" % (x, y, r, colour)


def style_of(name, extra):
    if name in STYLE:
        return STYLE[name]
    if name not in extra:
        extra[name] = (FALLBACK_COLOURS[len(extra) % len(FALLBACK_COLOURS)], "circle")
    return extra[name]


def panel(svg, x0, y0, title, ylabel, series, xvals, styles, unit, exhaustive=None, whiskers=None):
    """series: {method: [(n, value), ...]} (values > 0). whiskers: {method:
    {n: value}}, drawn as a thin vertical line from the point to the value
    with a cap (the mean next to the median). exhaustive: names of
    methods left out of series because they compute n distances per query,
    drawn as one grey line y = n instead."""
    px0, py0 = x0 + MARGIN_L, y0 + MARGIN_T
    pw, ph = PANEL_W - MARGIN_L - MARGIN_R, PANEL_H - MARGIN_T - MARGIN_B
    svg.append("<text x='%.1f' y='%.1f' font-size='13' font-weight='bold' text-anchor='middle' %s>%s</text>" %
               (px0 + pw / 2, y0 + 18, FONT, escape(title)))
    yvals = [v for pts in series.values() for _, v in pts] + (list(xvals) if exhaustive else [])
    yvals += [v for w in (whiskers or {}).values() for v in w.values()]
    svg.append("<rect x='%d' y='%d' width='%d' height='%d' fill='white' stroke='#444'/>" % (px0, py0, pw, ph))
    if not yvals:
        svg.append("<text x='%.1f' y='%.1f' font-size='12' text-anchor='middle' fill='#666' %s>no data</text>" %
                   (px0 + pw / 2, py0 + ph / 2, FONT))
        return
    xlo, xhi = log_range(xvals, 0.1)
    ylo, yhi = log_range(yvals, 0.08)
    X = lambda n: px0 + (math.log10(n) - xlo) / (xhi - xlo) * pw
    Y = lambda v: py0 + ph - (math.log10(v) - ylo) / (yhi - ylo) * ph
    # Grid and ticks.
    for t in decade_ticks(ylo, yhi):
        y = py0 + ph - (t - ylo) / (yhi - ylo) * ph
        major = abs(t - round(t)) < 1e-9
        svg.append("<line x1='%d' y1='%.1f' x2='%d' y2='%.1f' stroke='%s' stroke-width='1'/>" %
                   (px0, y, px0 + pw, y, "#ccc" if major else "#eee"))
        svg.append("<text x='%d' y='%.1f' font-size='11' text-anchor='end' %s>%s</text>" %
                   (px0 - 5, y + 4, FONT, si(10 ** t)))
    for t in decade_ticks(xlo, xhi):
        if abs(t - round(t)) < 1e-9:
            x = px0 + (t - xlo) / (xhi - xlo) * pw
            svg.append("<line x1='%.1f' y1='%d' x2='%.1f' y2='%d' stroke='#eee'/>" % (x, py0, x, py0 + ph))
    for n in xvals:
        svg.append("<line x1='%.1f' y1='%d' x2='%.1f' y2='%d' stroke='#ccc'/>" % (X(n), py0, X(n), py0 + ph))
        svg.append("<text x='%.1f' y='%d' font-size='11' text-anchor='middle' %s>%s</text>" %
                   (X(n), py0 + ph + 15, FONT, si(n)))
    svg.append("<text x='%.1f' y='%d' font-size='11' text-anchor='middle' %s>database size n (vectors, log)</text>" %
               (px0 + pw / 2, py0 + ph + 32, FONT))
    svg.append("<text transform='translate(%d,%.1f) rotate(-90)' font-size='11' text-anchor='middle' %s>%s</text>" %
               (x0 + 16, py0 + ph / 2, FONT, escape(ylabel)))
    if exhaustive:
        svg.append("<polyline fill='none' stroke='#999' stroke-width='6' stroke-opacity='0.5' points='%s'/>" %
                   " ".join("%.1f,%.1f" % (X(n), Y(n)) for n in xvals))
        # Names in the top-left corner, which the rising y = n line leaves free.
        for i, t in enumerate(["grey band: n, every distance:"] + list(exhaustive)):
            svg.append("<text x='%.1f' y='%.1f' font-size='10' fill='#555' %s>%s</text>" %
                       (px0 + 5, py0 + 13 + 11 * i, FONT, escape(t)))
    # Lines, then markers on top.
    order = list(styles)
    for name, pts in series.items():
        colour, shape = styles[name]
        pts = sorted(pts)
        dx = 2.5 * (order.index(name) - (len(order) - 1) / 2)  # whiskers side by side
        dash = "" if name in EXACT else " stroke-dasharray='6,4'"
        if len(pts) > 1:
            svg.append("<polyline fill='none' stroke='%s' stroke-width='2'%s points='%s'/>" %
                       (colour, dash, " ".join("%.1f,%.1f" % (X(n), Y(v)) for n, v in pts)))
        for n, v in pts:
            w = (whiskers or {}).get(name, {}).get(n)
            if w is not None and w >= WHISKER_MIN_RATIO * v:
                svg.append("<line x1='%.1f' y1='%.1f' x2='%.1f' y2='%.1f' stroke='%s' stroke-width='1.2'/>"
                           "<line x1='%.1f' y1='%.1f' x2='%.1f' y2='%.1f' stroke='%s' stroke-width='1.5'/>" %
                           (X(n) + dx, Y(v), X(n) + dx, Y(w), colour, X(n) + dx - 4, Y(w), X(n) + dx + 4, Y(w),
                            colour))
            svg.append("<g>%s<title>%s n=%s: %s %s</title></g>" %
                       (marker(shape, X(n), Y(v), colour), escape(name), si(n), "%.4g" % v, unit))


def plot(suite, out_path):
    runs = suite["runs"]
    dims = sorted({r["result"]["data"]["dim"] for r in runs})
    names = []
    for r in runs:
        for m in r["result"]["methods"]:
            if m["name"] not in names:
                names.append(m["name"])
    extra = {}
    styles = {n: style_of(n, extra) for n in names}
    desc_name = {r["result"]["data"]["dim"]: r.get("descriptor_name", "dim %d" % r["result"]["data"]["dim"])
                 for r in runs}

    ncol = max(1, len(dims))
    width = ncol * PANEL_W + (ncol - 1) * GAP_X + LEGEND_W + 20
    top = 60
    height = top + 2 * PANEL_H + GAP_Y + 20
    svg = ["<svg xmlns='http://www.w3.org/2000/svg' width='%d' height='%d' viewBox='0 0 %d %d'>" %
           (width, height, width, height),
           "<rect width='100%' height='100%' fill='white'/>"]
    host = suite.get("host", {})
    svg.append("<text x='12' y='22' font-size='15' font-weight='bold' %s>k-NN search, single thread, k=%s: "
               "time and exact distance computations per query</text>" % (FONT, suite.get("k")))
    svg.append("<text x='12' y='42' font-size='11' fill='#444' %s>%s; %s; %s</text>" % (
        FONT, escape(host.get("cpu", "")), escape(suite.get("command") or ""), escape(suite.get("date") or "")))

    for col, dim in enumerate(dims):
        x0 = col * (PANEL_W + GAP_X)
        time_series, dist_series, means, xs = {}, {}, {}, set()
        for r in runs:
            data = r["result"]["data"]
            if data["dim"] != dim:
                continue
            xs.add(data["n"])
            for m in r["result"]["methods"]:
                if "error" in m:
                    continue
                t = m.get("us_per_query_single_median")
                if t and t > 0:
                    time_series.setdefault(m["name"], []).append((data["n"], t))
                    mean = m.get("us_per_query_single_mean")
                    if mean and mean > 0:
                        means.setdefault(m["name"], {})[data["n"]] = mean
                d = m.get("distance_computations_per_query")
                if d is not None and d > 0:
                    dist_series.setdefault(m["name"], []).append((data["n"], d))
        xs = sorted(xs)
        # Methods that compute every distance (dist/q == n at every size) share one line.
        exhaustive = [name for name, pts in dist_series.items() if all(abs(v - n) < 0.5 for n, v in pts)]
        for name in exhaustive:
            del dist_series[name]
        title = desc_name.get(dim, "dim %d" % dim)
        panel(svg, x0, top, title, "us per query (one query per call, log)", time_series, xs, styles,
              "us/query (median)", whiskers=means)
        panel(svg, x0, top + PANEL_H + GAP_Y, "%s: distance computations" % title.split(" (")[0],
              "exact distances per query (log)", dist_series, xs, styles, "distances/query", exhaustive)

    # Legend.
    lx = ncol * (PANEL_W + GAP_X) + 5
    ly = top + MARGIN_T
    svg.append("<text x='%d' y='%d' font-size='12' font-weight='bold' %s>method</text>" % (lx, ly - 8, FONT))
    for i, name in enumerate(names):
        colour, shape = styles[name]
        y = ly + 10 + i * 22
        dash = "" if name in EXACT else " stroke-dasharray='6,4'"
        svg.append("<line x1='%d' y1='%d' x2='%d' y2='%d' stroke='%s' stroke-width='2'%s/>" %
                   (lx, y, lx + 34, y, colour, dash))
        svg.append(marker(shape, lx + 17, y, colour))
        svg.append("<text x='%d' y='%d' font-size='12' %s>%s</text>" % (lx + 42, y + 4, FONT, escape(name)))
    ny = ly + 10 + len(names) * 22 + 10
    notes = ["solid: exact; dashed: approximate",
             "time: median of one query per call;",
             "whisker up to a cap: the mean,",
             "drawn where >= 1.25 x the median;",
             "identical curves overlap",
             "(e.g. ffva-2nn under ffva-knn);",
             "distances: grey band = n, methods",
             "computing every distance (named);",
             "faiss-hnsw counts level 0 only;",
             "flann reports none"]
    for i, t in enumerate(notes):
        svg.append("<text x='%d' y='%d' font-size='11' fill='#444' %s>%s</text>" % (lx, ny + i * 15, FONT, escape(t)))
    svg.append("</svg>")
    with open(out_path, "w") as f:
        f.write("\n".join(svg) + "\n")


def main():
    if len(sys.argv) not in (2, 3) or sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        sys.exit(2)
    src = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) == 3 else os.path.join(os.path.dirname(os.path.abspath(src)), "knn_suite.svg")
    with open(src) as f:
        suite = json.load(f)
    plot(suite, out)
    print("wrote %s" % out)


if __name__ == "__main__":
    main()
