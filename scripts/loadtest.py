#!/usr/bin/env python3
"""Load test of `mvkp serve` (issue 7): C concurrent clients POST frames to
/api/recognize for D seconds on loopback; reports throughput, p50/p99
latency, errors by status, and the server's RSS before and after (after a
warm-up).

  scripts/loadtest.py --mvkp build/mvkp --db DB --frames DIR_OR_FILES...
                      [--clients 16] [--seconds 60] [--threads 2]
                      [--max-inflight N] [--json OUT]

It starts the server itself (on a free port) so it can read its RSS from
/proc. Frames are sent as they are (JPEG/PNG), round-robin per client.
"""
import argparse
import http.client
import json
import os
import signal
import statistics
import subprocess
import sys
import threading
import time


def rss_kb(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mvkp", default="build/mvkp")
    ap.add_argument("--db", required=True)
    ap.add_argument("--frames", nargs="+", required=True)
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=60)
    ap.add_argument("--warmup", type=float, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--max-inflight", type=int, default=0, help="0: the server's default (2 x threads)")
    ap.add_argument("--json")
    a = ap.parse_args()

    files = []
    for f in a.frames:
        if os.path.isdir(f):
            files += sorted(os.path.join(f, x) for x in os.listdir(f) if x.lower().endswith((".jpg", ".jpeg", ".png")))
        else:
            files.append(f)
    if not files:
        sys.exit("loadtest: no frames")
    frames = [(open(f, "rb").read(), "image/png" if f.lower().endswith(".png") else "image/jpeg") for f in files]

    cmd = [a.mvkp, "serve", a.db, "--port", "0", "--threads", str(a.threads)]
    if a.max_inflight:
        cmd += ["--max-inflight", str(a.max_inflight)]
    srv = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    port = json.loads(srv.stderr.readline())["port"]
    # Drain the server's log lines so its stderr pipe never fills.
    threading.Thread(target=lambda: [None for _ in srv.stderr], daemon=True).start()

    lock = threading.Lock()
    lat, status = [], {}
    phase = {"record": False, "stop": False}

    def client(k):
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
        i = k
        while not phase["stop"]:
            body, ctype = frames[i % len(frames)]
            i += 1
            t0 = time.perf_counter()
            try:
                conn.request("POST", "/api/recognize", body, {"Content-Type": ctype})
                r = conn.getresponse()
                r.read()
                code = r.status
            except Exception:
                code = "exception"
                conn.close()
                conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
            dt = (time.perf_counter() - t0) * 1000
            if phase["record"]:
                with lock:
                    status[code] = status.get(code, 0) + 1
                    if code == 200:
                        lat.append(dt)

    workers = [threading.Thread(target=client, args=(k,)) for k in range(a.clients)]
    rss0 = rss_kb(srv.pid)
    for w in workers:
        w.start()
    time.sleep(a.warmup)
    rss_warm = rss_kb(srv.pid)
    phase["record"] = True
    t0 = time.time()
    time.sleep(a.seconds)
    phase["record"] = False
    elapsed = time.time() - t0
    rss_end = rss_kb(srv.pid)
    phase["stop"] = True
    for w in workers:
        w.join()
    srv.send_signal(signal.SIGTERM)
    srv.wait(timeout=30)

    ok = status.get(200, 0)
    q = sorted(lat)
    res = {
        "clients": a.clients, "seconds": round(elapsed, 1), "server_threads": a.threads, "frames": len(files),
        "requests": sum(status.values()), "ok": ok, "status": {str(k): v for k, v in status.items()},
        "throughput_rps": round(ok / elapsed, 1),
        "p50_ms": round(statistics.median(q), 1) if q else None,
        "p99_ms": round(q[min(len(q) - 1, int(0.99 * len(q)))], 1) if q else None,
        "rss_start_mb": round(rss0 / 1024, 1), "rss_after_warmup_mb": round(rss_warm / 1024, 1),
        "rss_end_mb": round(rss_end / 1024, 1),
        "rss_growth_after_warmup_pct": round(100.0 * (rss_end - rss_warm) / max(1, rss_warm), 1),
    }
    print(json.dumps(res, indent=1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
