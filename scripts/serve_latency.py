#!/usr/bin/env python3
"""Latency of `mvkp serve` against 100 exhibits (issue 7): POST /api/recognize
with 640x480 JPEG gallery frames on loopback, end to end as the client sees
it, with the server on 2 threads.

  scripts/serve_latency.py --mvkp build/mvkp --set out/gallery/set
      --pool DIR... [--exhibits 100] [--clients 1] [--reps 2] [--json OUT]
      [--serve-args "..."]

Exhibits: the gallery's targets (scripts/gallery-eval.sh makes the set, with
ground truth) plus distractor exhibits up to --exhibits: 2x2 mosaics of
crops of the --pool images, mirrored, so that they are real-looking pictures
that appear in no frame (the WH descriptors are not mirror-invariant). The
database is built once with `mvkp db import` (kept in OUT's folder).

Frames: the set's scenes (1-3 exhibits each) and no-target frames, sent in
order, --reps times, by --clients clients on keep-alive connections after a
warm-up. Reports median / p90 / p99 / max latency, the server's own timings,
top-1 hits and wrong ids against the ground truth, and false detections in
no-target frames.
"""
import argparse
import http.client
import json
import os
import random
import re
import statistics
import subprocess
import sys
import threading
import time

import cv2
import numpy as np


def pct(xs, p):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100.0 * (len(xs) - 1))))] if xs else float("nan")


def make_distractors(pool, n, out_dir, seed):
    os.makedirs(out_dir, exist_ok=True)
    rng = random.Random(seed)
    imgs = []
    for f in pool:
        im = cv2.imread(f, cv2.IMREAD_COLOR)
        if im is not None and im.shape[0] >= 180 and im.shape[1] >= 240:
            imgs.append(im)
    if len(imgs) < 4:
        sys.exit("serve_latency: need at least 4 pool images of 240x180 or more")
    rows = []
    for i in range(n):
        tiles = []
        for _ in range(4):
            im = imgs[rng.randrange(len(imgs))]
            h, w = im.shape[:2]
            s = rng.uniform(0.5, 1.0)
            cw, ch = max(240, int(w * s)), max(180, int(h * s))
            cw, ch = min(cw, w), min(ch, h)
            x, y = rng.randrange(w - cw + 1), rng.randrange(h - ch + 1)
            tiles.append(cv2.resize(im[y:y + ch, x:x + cw], (240, 180), interpolation=cv2.INTER_AREA))
        mosaic = cv2.flip(np.vstack([np.hstack(tiles[:2]), np.hstack(tiles[2:])]), 1)
        path = os.path.join(out_dir, "distractor_%03d.jpg" % i)
        cv2.imwrite(path, mosaic, [cv2.IMWRITE_JPEG_QUALITY, 92])
        rows.append(("distractor_%03d" % i, path))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mvkp", default="build/mvkp")
    ap.add_argument("--set", required=True, help="scripts/make-gallery.py output (scenes, notarget, ground truth)")
    ap.add_argument("--pool", nargs="+", default=[], help="images (or folders) for distractor exhibits")
    ap.add_argument("--exhibits", type=int, default=100)
    ap.add_argument("--clients", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--notarget", type=int, default=50, help="no-target frames used")
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--work", default=None, help="folder for the database and distractors (default: next to --json)")
    ap.add_argument("--serve-args", default="")
    ap.add_argument("--json")
    a = ap.parse_args()

    gt = json.load(open(os.path.join(a.set, "ground_truth.json")))
    work = a.work or os.path.join(os.path.dirname(os.path.abspath(a.json or "out/serve-latency/x")), "work")
    os.makedirs(work, exist_ok=True)
    targets = gt["targets"]
    n_extra = max(0, a.exhibits - len(targets))
    db = os.path.join(work, "exhibits-%d.db" % (len(targets) + n_extra))
    if not os.path.exists(db):
        pool = []
        for p in a.pool:
            if os.path.isdir(p):
                for root, _, names in os.walk(p):
                    pool += [os.path.join(root, x) for x in sorted(names) if x.lower().endswith((".jpg", ".png"))]
            else:
                pool.append(p)
        # Nothing that can appear in a frame: not the targets' sources (a
        # mirrored crop of a symmetric picture, a butterfly, still matches it)
        # nor the backgrounds.
        used = {os.path.basename(t.get("source", t["file"])) for t in targets.values()}
        used |= {os.path.basename(t["file"]) for t in targets.values()}
        used |= {b.split("_", 1)[1] if b[:3] in ("oc_", "sk_") else b for b in gt.get("backgrounds", [])}
        # ... nor their siblings (basketball1/2, aloeL/R, left01/right01: one
        # scene twice).
        def family(name):
            stem = os.path.splitext(name)[0].lower()
            if re.fullmatch(r"(left|right)\d+", stem):
                return "left/right"
            return re.sub(r"(\d+|l|r|a|b)$", "", stem) or stem
        used_families = {family(u) for u in used}
        pool = [f for f in pool if os.path.basename(f) not in used and family(os.path.basename(f)) not in used_families]
        rows = [(tid, os.path.join(a.set, t["file"])) for tid, t in targets.items()]
        rows += make_distractors(pool, n_extra, os.path.join(work, "distractors"), a.seed)
        csv = os.path.join(work, "exhibits.csv")
        with open(csv, "w") as f:
            f.write("id,image,title\n")
            for tid, path in rows:
                f.write("%s,%s,%s\n" % (tid, os.path.abspath(path), tid))
        tmp = db + ".tmp"
        for x in (tmp, tmp + "-wal", tmp + "-shm"):
            if os.path.exists(x):
                os.remove(x)
        t0 = time.time()
        subprocess.run([a.mvkp, "db", "create", tmp], check=True, stdout=subprocess.DEVNULL)
        subprocess.run([a.mvkp, "db", "import", tmp, csv], check=True, stdout=subprocess.DEVNULL)
        os.replace(tmp, db)
        print("serve_latency: built %s (%d exhibits) in %.0f s" % (db, len(rows), time.time() - t0), flush=True)

    frames, negatives = [], []  # (bytes, true ids (empty: no target), name)
    for fr in gt["frames"]:
        ids = sorted({o["id"] for o in fr.get("objects", [])})
        (frames if ids else negatives).append((fr["file"], ids))
    if negatives and a.notarget > 0:  # evenly over the kinds of no-target frame
        step = max(1, len(negatives) // a.notarget)
        frames += negatives[::step][: a.notarget]
    frames = [(open(os.path.join(a.set, f), "rb").read(), ids, f) for f, ids in frames]
    if not frames:
        sys.exit("serve_latency: no frames")

    cmd = [a.mvkp, "serve", db, "--port", "0", "--threads", str(a.threads), "--max-inflight", "64"] + a.serve_args.split()
    srv = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    try:
        first = json.loads(srv.stderr.readline())
        port = int(first["port"])
        threading.Thread(target=lambda: [None for _ in srv.stderr], daemon=True).start()

        def post(conn, body):
            for attempt in range(2):
                try:
                    t = time.perf_counter()
                    conn.request("POST", "/api/recognize", body=body, headers={"Content-Type": "image/jpeg"})
                    r = conn.getresponse()
                    data = r.read()
                    ms = (time.perf_counter() - t) * 1000
                    if r.getheader("Connection", "").lower() == "close":
                        conn.close()
                    return r.status, json.loads(data), ms
                except (http.client.HTTPException, ConnectionError, OSError):
                    conn.close()
                    if attempt:
                        raise
            raise RuntimeError("unreachable")

        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
        for i in range(a.warmup):
            post(conn, frames[i % len(frames)][0])
        conn.close()

        jobs = [f for _ in range(a.reps) for f in frames]
        results = [None] * len(jobs)
        next_job = [0]
        lock = threading.Lock()

        def client():
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
            while True:
                with lock:
                    j = next_job[0]
                    next_job[0] += 1
                if j >= len(jobs):
                    break
                results[j] = post(c, jobs[j][0])
            c.close()

        t0 = time.perf_counter()
        th = [threading.Thread(target=client) for _ in range(a.clients)]
        for t in th:
            t.start()
        for t in th:
            t.join()
        wall = time.perf_counter() - t0
    finally:
        srv.terminate()
        srv.wait(timeout=30)

    lat, rec, errors = [], [], 0
    hits = inst = wrong = false_pos = neg_frames = 0
    examples = []
    for (body, ids, name), (status, js, ms) in zip(jobs, results):
        if status != 200:
            errors += 1
            continue
        lat.append(ms)
        rec.append(js["time_ms"]["recognize"])
        got = [f["id"] for f in js["found"]]
        if ids:
            inst += len(ids)
            hits += sum(1 for x in ids if x in got)
            wrong += sum(1 for x in got if x not in ids)
        else:
            neg_frames += 1
            false_pos += bool(got)
        if any(x not in ids for x in got) and len(examples) < 20:
            examples.append({"frame": name, "truth": ids, "found": got})
    out = {
        "exhibits": len(targets) + n_extra,
        "requests": len(jobs),
        "clients": a.clients,
        "server_threads": a.threads,
        "serve_args": a.serve_args,
        "errors": errors,
        "latency_ms": {"median": statistics.median(lat), "p90": pct(lat, 90), "p99": pct(lat, 99), "max": max(lat),
                       "mean": statistics.mean(lat)},
        "server_recognize_ms": {"median": statistics.median(rec), "p99": pct(rec, 99)},
        "throughput_rps": len(jobs) / wall,
        "instances_found": hits,
        "instances": inst,
        "wrong_ids": wrong,
        "notarget_frames": neg_frames,
        "notarget_false": false_pos,
        "wrong_examples": examples,
    }
    print(json.dumps(out, indent=1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
