#!/usr/bin/env python3
"""Per-frame matching time through Python vs the C++ path (issue 9: <= 5 % overhead).

Both sides match the same frames (generated views of a sample target, written
as PNG and decoded by mvkp's own loader on both sides) with the same model file
and default MatchOptions, single-threaded (OpenCV threads = 1, as the CLI):

  C++     mvkp_match_bench (python/bench/match_bench.cc): LoadModel, LoadImageGray,
          Matcher::Match timed with steady_clock per call.
  Python  mvkp.Matcher(mvkp.Model.load(...)).match(frame) timed with
          time.perf_counter per call, reading result.found and result.outline.

Per frame the median over rounds is taken, then the mean over frames ("median"
figure), and likewise the fastest round ("min" figure, the intrinsic cost, less
sensitive to other work on a shared machine); the two sides alternate in
blocks and the best block of each side is compared. The overhead reported is
the min figure's; both are printed. binding_overhead_percent isolates the
binding: per call, the wall time outside the matcher's own stage timings
(MatchResult time), Python minus C++, relative to the C++ frame time.
in_process_overhead_percent: the same Matcher called on the same frames from
C++ (a loop inside the module) and from Python, pass by pass alternately in
one process, so load on a shared machine hits both sides alike (per-frame
medians; _min: fastest rounds). Prints one JSON line; with --max-overhead P exits 1 when
the overhead exceeds P percent.

  PYTHONPATH=build/python python3 python/bench_overhead.py --bench build/python/mvkp_match_bench
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# Import the built module (PYTHONPATH), not the source package beside this script.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
import mvkp  # noqa: E402


def python_block(matcher, frames, rounds):
    per = [[] for _ in frames]
    outside = []
    for f in frames:
        matcher.match(f)  # warm-up
    for _ in range(rounds):
        for i, f in enumerate(frames):
            t0 = time.perf_counter()
            r = matcher.match(f)
            if r.found:
                r.outline
            per[i].append((time.perf_counter() - t0) * 1000.0)
            outside.append(per[i][-1] - r.time_ms["total"])
    return (statistics.mean(statistics.median(p) for p in per), statistics.mean(min(p) for p in per),
            statistics.median(outside))


def interleaved(matcher, frames, rounds):
    """C++ and Python passes over the frames, alternating, in this process."""
    from mvkp import _mvkp

    cpp = [[] for _ in frames]
    py = [[] for _ in frames]
    for r in range(rounds):
        for side in ((0, 1) if r % 2 == 0 else (1, 0)):
            if side == 0:
                for i, ms in enumerate(_mvkp._time_match_cpp(matcher, frames)):
                    cpp[i].append(ms)
            else:
                for i, f in enumerate(frames):
                    t0 = time.perf_counter()
                    res = matcher.match(f)
                    if res.found:
                        res.outline
                    py[i].append((time.perf_counter() - t0) * 1000.0)
    med = lambda x: statistics.mean(statistics.median(p) for p in x)  # noqa: E731
    low = lambda x: statistics.mean(min(p) for p in x)  # noqa: E731
    return med(cpp), med(py), low(cpp), low(py)


def cpp_block(bench, model_path, frame_paths, rounds):
    out = subprocess.run([bench, str(rounds), model_path, *frame_paths], check=True, capture_output=True, text=True)
    r = json.loads(out.stdout)
    return r["mean_ms"], r["mean_min_ms"], r["outside_stages_ms"]


def main():
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bench", default=os.environ.get("MVKP_MATCH_BENCH"), help="mvkp_match_bench binary")
    ap.add_argument("--target", default=str(here.parent / "samples" / "starry_night.jpg"))
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=5, help="timed passes over the frames per block")
    ap.add_argument("--blocks", type=int, default=3, help="alternating C++ / Python blocks")
    ap.add_argument("--max-overhead", type=float, default=None, help="exit 1 above this many percent")
    a = ap.parse_args()
    if not a.bench:
        sys.exit("bench_overhead.py: give --bench (build/python/mvkp_match_bench) or set MVKP_MATCH_BENCH")
    mvkp.set_num_threads(1)
    target = mvkp.prepare_target(mvkp.load_image(a.target), 320)
    with tempfile.TemporaryDirectory() as tmp:
        model_path = os.path.join(tmp, "target.mvkp")
        mvkp.train(target, seed=42).save(model_path)
        frame_paths = []
        for s in range(a.frames):
            img, _ = mvkp.make_scene_view(target, 1000 + s)
            p = os.path.join(tmp, f"frame{s:03d}.png")
            mvkp.save_image(p, img)
            frame_paths.append(p)
        frames = [mvkp.load_image(p) for p in frame_paths]
        matcher = mvkp.Matcher(mvkp.Model.load(model_path))
        found = sum(bool(matcher.match(f)) for f in frames)
        cpp, py = [], []
        for _ in range(a.blocks):
            cpp.append(cpp_block(a.bench, model_path, frame_paths, a.rounds))
            py.append(python_block(matcher, frames, a.rounds))
        ic_med, ip_med, ic_min, ip_min = interleaved(matcher, frames, a.rounds * a.blocks)
    c_med, p_med = min(x[0] for x in cpp), min(x[0] for x in py)
    c, p = min(x[1] for x in cpp), min(x[1] for x in py)
    overhead = (p / c - 1.0) * 100.0
    # The binding's own cost per call: wall time not spent in the matcher's
    # stages, Python minus C++ (same process each; immune to machine noise).
    call_py, call_cpp = statistics.median(x[2] for x in py), statistics.median(x[2] for x in cpp)
    print(json.dumps({"frames": a.frames, "found": found, "rounds": a.rounds, "blocks": a.blocks,
                      "cpp_ms_per_frame": round(c, 4), "python_ms_per_frame": round(p, 4),
                      "overhead_percent": round(overhead, 2),
                      "cpp_median_ms_per_frame": round(c_med, 4), "python_median_ms_per_frame": round(p_med, 4),
                      "overhead_median_percent": round((p_med / c_med - 1.0) * 100.0, 2),
                      "call_cost_python_ms": round(call_py, 4), "call_cost_cpp_ms": round(call_cpp, 4),
                      "binding_overhead_percent": round((call_py - call_cpp) / c * 100.0, 2),
                      "in_process_cpp_ms_per_frame": round(ic_med, 4), "in_process_python_ms_per_frame": round(ip_med, 4),
                      "in_process_overhead_percent": round((ip_med / ic_med - 1.0) * 100.0, 2),
                      "in_process_overhead_min_percent": round((ip_min / ic_min - 1.0) * 100.0, 2),
                      "cpp_blocks": [[round(v, 4) for v in x] for x in cpp],
                      "python_blocks": [[round(v, 4) for v in x] for x in py]}))
    if a.max_overhead is not None and overhead > a.max_overhead:
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
