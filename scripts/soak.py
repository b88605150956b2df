#!/usr/bin/env python3
"""Soak of `mvkp serve` (issue 19, item 5): C concurrent loopback clients for
D seconds, mixed like a museum day, then the slow-socket latency phase.

  scripts/soak.py --mvkp build/mvkp --out out/soak [--seconds 600] [--clients 32]
                  [--rss-check growth|bound] [--rss-limit-mb 1024] [--fail-on-slow-ratio]

Setup (all under OUT/work): a copy of the binary (the build may relink while
we run), a fresh exhibit database of five bundled samples (samples/*.jpg),
an admin token file, 640x480 JPEG query frames of each exhibit made by
`mvkp synth` (and frames of samples/astronaut.jpg, which is no exhibit),
and a picture drawn with OpenCV for the exhibit the admin clients add and
delete. The server runs on a free loopback port (--port 0) with its
defaults; its log goes to OUT/server.log. A preflight recognises every frame
three times (no hint, with ?prev=, with a temporary exhibit loaded) and
keeps the frames that are right every time, so that a wrong answer under
load means the load changed it.

Clients (32 by default: 18 recognition, 8 readers, 2 admin, 4 slow sockets):
  - recognition: like the web client, frames of one exhibit in a row with
    ?prev= the last found ids, a JPEG body (sometimes multipart), checking
    that a frame of exhibit X finds exactly X and a no-exhibit frame nothing;
  - readers: GET /api/exhibits, /api/exhibits/{id} (sometimes an unknown id:
    404), /api/exhibits/{id}/image with ?thumb=N for several N (the JPEG's
    longest side checked, sometimes If-None-Match: 304), the full image;
  - admin: PUT metadata with the bearer token (the answer checked), GET
    /api/exhibits/{id}/quality, and now and then POST a new exhibit, read
    it, DELETE it, read it again (404);
  - slow sockets: open a connection, trickle a request (headers, or the body
    of a POST) a byte every 1.5-4 s, abandon it after 3-45 s (close or
    reset) unless the server closes it first; again and again.
A sampler reads the server's VmRSS and /proc/PID/fd every --sample-s, and
a prober times GET /healthz on a fresh connection as often (neither counts
among the clients).

Then, as its own phase, recognition p99 of one sequential client (a fresh
connection per frame) alone and while 8 slow sockets stay open (reopened
when the server closes them), in alternating rounds so that a neighbour's
CPU load hits both alike; the ratio's goal is <= 2 (issue 19).

Writes OUT/report.json and OUT/summary.txt. Exit status 1 when a goal fails:
any 5xx other than deliberate 503s (Retry-After / "busy"), a request lost
(timeout, reset) by a regular client, a wrong recognition, an unexpected
status or malformed answer, RSS growth > 5 % from the first sample after
the warm-up (the first 20 % of the run) to the last (or, with --rss-check
bound, RSS above --rss-limit-mb), descriptors not flat (last sample above
the post-warm-up median + a margin, or not back to the idle count once the
load has stopped), the server dying or not stopping cleanly. The
slow-socket ratio fails the run only with --fail-on-slow-ratio.

Standard library only, plus python3-opencv (Debian) for JPEG encoding.
"""
import argparse
import hashlib
import http.client
import json
import math
import os
import random
import select
import shutil
import signal
import socket
import statistics
import struct
import subprocess
import sys
import threading
import time
import urllib.parse
import uuid

HOST = "127.0.0.1"
TOKEN = "soak-admin-token-0123456789abcdef"
# id, sample, title, artist, year
EXHIBITS = [
    ("starry-night", "starry_night.jpg", "The Starry Night", "Vincent van Gogh", "1889"),
    ("building", "building.jpg", "Building", "Unknown", "1900"),
    ("baboon", "baboon.jpg", "Baboon", "Unknown", "1973"),
    ("fruits", "fruits.jpg", "Fruits", "Unknown", "1990"),
    ("coffee", "coffee.jpg", "Coffee", "Unknown", "2000"),
]
NEGATIVE_SAMPLE = "astronaut.jpg"  # no exhibit: its frames must find nothing
THUMBS = [16, 32, 64, 128, 256, 512, 1024]


def log(msg):
    print("soak %s: %s" % (time.strftime("%H:%M:%S"), msg), flush=True)


def pct(values, p):
    """Nearest-rank percentile (p in 0..100) of a list, or None."""
    if not values:
        return None
    s = sorted(values)
    return s[max(0, min(len(s) - 1, math.ceil(p / 100.0 * len(s)) - 1))]


def slope_per_min(points):
    """Least-squares slope of (t s, y) points, per minute, or None."""
    if len(points) < 3:
        return None
    mt = statistics.mean(t for t, _ in points)
    my = statistics.mean(y for _, y in points)
    den = sum((t - mt) ** 2 for t, _ in points)
    return 60 * sum((t - mt) * (y - my) for t, y in points) / den if den else None


def r1(x):
    return None if x is None else round(x, 1)


# ---------------------------------------------------------------- setup

def wait_for_binary(path, limit_s=600):
    """The other engineer's build may relink the binary: wait until it exists
    and has not changed for 2 s, then copy it so relinks cannot touch us."""
    t0 = time.time()
    last = None
    while True:
        try:
            st = os.stat(path)
            cur = (st.st_size, st.st_mtime)
            if cur == last and os.access(path, os.X_OK):
                return
            last = cur
        except FileNotFoundError:
            last = None
        if time.time() - t0 > limit_s:
            sys.exit("soak: %s missing or changing for %d s" % (path, limit_s))
        time.sleep(2)


def copy_binary(src, dst):
    for attempt in range(30):
        wait_for_binary(src)
        try:
            shutil.copy2(src, dst)
            r = subprocess.run([dst, "--help"], capture_output=True, timeout=60)
            if r.returncode == 0:
                return
        except (OSError, subprocess.SubprocessError):
            pass
        time.sleep(5)
    sys.exit("soak: cannot copy a working %s" % src)


def run(mvkp, *args):
    r = subprocess.run([mvkp, *args], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        sys.exit("soak: setup failed: mvkp %s\n%s%s" % (" ".join(args), r.stdout, r.stderr))
    return r.stdout


def make_setup(mvkp, samples, work, views, seed):
    import cv2  # python3-opencv (scripts/install-deps.sh)
    import numpy as np
    db = os.path.join(work, "museum.db")
    run(mvkp, "db", "create", db)
    for eid, sample, title, artist, year in EXHIBITS:
        run(mvkp, "db", "add", db, "--id", eid, "--image", os.path.join(samples, sample), "--title", title,
            "--artist", artist, "--year", year, "--url", "https://example.org/" + eid)
    token_file = os.path.join(work, "admin-token")
    with open(token_file, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(token_file, 0o600)
    frames = []  # dicts: name, body (JPEG bytes), expected (exhibit id or None)
    fdir = os.path.join(work, "frames")
    os.makedirs(fdir, exist_ok=True)
    sources = [(eid, sample) for eid, sample, *_ in EXHIBITS] + [(None, NEGATIVE_SAMPLE)]
    for k, (eid, sample) in enumerate(sources):
        sdir = os.path.join(work, "synth-" + (eid or "none"))
        run(mvkp, "synth", os.path.join(samples, sample), "--n", str(views), "--seed", str(seed + k), "-o", sdir)
        for v in sorted(x for x in os.listdir(sdir) if x.startswith("view_") and x.endswith(".png")):
            img = cv2.imread(os.path.join(sdir, v), cv2.IMREAD_COLOR)
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 85])  # like the web client
            if not ok:
                sys.exit("soak: cannot encode " + v)
            name = "%s-%s.jpg" % (eid or "none", v[:-4])
            with open(os.path.join(fdir, name), "wb") as f:
                f.write(buf.tobytes())
            frames.append({"name": name, "body": buf.tobytes(), "expected": eid})
    # The picture the admin clients add and delete: shapes on noise, in no frame.
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.integers(0, 255, (300, 400, 3), dtype=np.uint8), (0, 0), 3)
    for _ in range(60):
        c = tuple(int(x) for x in rng.integers(0, 255, 3))
        x, y = int(rng.integers(0, 400)), int(rng.integers(0, 300))
        if rng.random() < 0.5:
            cv2.rectangle(img, (x, y), (x + int(rng.integers(8, 60)), y + int(rng.integers(8, 60))), c, -1)
        else:
            cv2.circle(img, (x, y), int(rng.integers(4, 30)), c, -1)
    cv2.putText(img, "soak", (120, 170), cv2.FONT_HERSHEY_SIMPLEX, 2.2, (255, 255, 255), 5)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    with open(os.path.join(work, "temporary-exhibit.jpg"), "wb") as f:
        f.write(buf.tobytes())
    return db, token_file, frames, buf.tobytes()


def start_server(mvkp, db, token_file, log_path, extra, env_vars):
    logf = open(log_path, "w")
    cmd = [mvkp, "serve", db, "--port", "0", "--admin-token-file", token_file, *extra]
    env = dict(os.environ, **dict(kv.split("=", 1) for kv in env_vars))
    p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=logf, env=env)
    logf.close()
    t0 = time.time()
    while time.time() - t0 < 120:
        with open(log_path) as f:
            line = f.readline()
        if line.endswith("\n"):
            try:
                j = json.loads(line)
                if j.get("event") == "listening":
                    return p, int(j["port"]), j, cmd
            except ValueError:
                pass
            p.kill()
            sys.exit("soak: server did not start: " + line)
        if p.poll() is not None:
            sys.exit("soak: server exited at start (rc %s): %s" % (p.returncode, open(log_path).read()[-2000:]))
        time.sleep(0.1)
    p.kill()
    sys.exit("soak: server did not print its port within 120 s")


# ---------------------------------------------------------------- HTTP

def multipart(fields):
    """fields: name -> bytes or str; returns (body, content type)."""
    b = uuid.uuid4().hex
    out = b""
    for k, v in fields.items():
        if isinstance(v, str):
            v = v.encode()
        fn = '; filename="%s.jpg"' % k if k == "image" else ""
        out += ("--%s\r\nContent-Disposition: form-data; name=\"%s\"%s\r\n\r\n" % (b, k, fn)).encode() + v + b"\r\n"
    out += ("--%s--\r\n" % b).encode()
    return out, "multipart/form-data; boundary=" + b


def jpeg_size(b):
    """(width, height) from a JPEG's SOF segment, or None."""
    if b[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 9 < len(b):
        if b[i] != 0xFF:
            i += 1
            continue
        m = b[i + 1]
        if m in (0xC0, 0xC1, 0xC2):
            return int.from_bytes(b[i + 7:i + 9], "big"), int.from_bytes(b[i + 5:i + 7], "big")
        i += 2 + int.from_bytes(b[i + 2:i + 4], "big")
    return None


def transport_kind(e):
    if isinstance(e, (socket.timeout, TimeoutError)):
        return "timeout"
    if isinstance(e, ConnectionRefusedError):
        return "refused"
    if isinstance(e, (ConnectionResetError, BrokenPipeError)):
        return "reset"
    if isinstance(e, (http.client.RemoteDisconnected, http.client.IncompleteRead)):
        return "closed"
    return "error"


class Client:
    """One keep-alive connection, reopened when the server closes it. A request
    that fails on a reused connection before any answer (the server closed an
    idle keep-alive connection) is retried once on a fresh one, as browsers do."""

    close_each = False  # --no-keep-alive: "Connection: close" on every request

    def __init__(self, port, timeout):
        self.port, self.timeout, self.conn, self.used = port, timeout, None, False
        self.retries = 0

    def close(self):
        if self.conn is not None:
            self.conn.close()
        self.conn, self.used = None, False

    def request(self, method, path, body=None, headers=None, fresh=False):
        """(status, headers dict (lower-case names), body bytes); raises on transport errors."""
        if fresh or self.close_each:
            self.close()
        if self.close_each:
            headers = dict(headers or {}, Connection="close")
        for attempt in (0, 1):
            if self.conn is None:
                self.conn = http.client.HTTPConnection(HOST, self.port, timeout=self.timeout)
                self.used = False
            reused = self.used
            try:
                self.conn.request(method, path, body, headers or {})
                self.used = True
                r = self.conn.getresponse()
                data = r.read()
                h = {k.lower(): v for k, v in r.getheaders()}
                if r.will_close:
                    self.close()
                return r.status, h, data
            except (http.client.RemoteDisconnected, ConnectionResetError, BrokenPipeError) as e:
                self.close()
                if reused and attempt == 0:
                    self.retries += 1
                    continue
                raise e
            except Exception:
                self.close()
                raise


# ---------------------------------------------------------------- statistics

class Stats:
    def __init__(self, t0):
        self.t0 = t0
        self.lock = threading.Lock()
        self.status = {}      # kind -> {status: n}
        self.lat = {}         # kind -> [ms] of 2xx/304 answers
        self.bad = []         # problems: dicts (first 200 kept)
        self.nbad = {}        # problem class -> n
        self.deliberate_503 = 0
        self.retries = 0

    def add(self, kind, status, ms):
        with self.lock:
            d = self.status.setdefault(kind, {})
            d[str(status)] = d.get(str(status), 0) + 1
            if isinstance(status, int) and (200 <= status < 300 or status == 304):
                self.lat.setdefault(kind, []).append(ms)

    def problem(self, cls, kind, detail):
        with self.lock:
            self.nbad[cls] = self.nbad.get(cls, 0) + 1
            if len(self.bad) < 200:
                self.bad.append({"t": round(time.monotonic() - self.t0, 1), "class": cls, "kind": kind,
                                 "detail": detail})


def call(stats, client, kind, method, path, body=None, headers=None, expect=(200,), fresh=False):
    """One request, counted under `kind`. Returns (status, headers, body) or None
    on a transport error. An answer with a status outside `expect` is a problem,
    except a deliberate 503 (Retry-After or "busy"), which the caller backs off from."""
    t = time.perf_counter()
    try:
        status, h, data = client.request(method, path, body, headers, fresh=fresh)
    except Exception as e:
        k = transport_kind(e)
        stats.add(kind, k, 0)
        stats.problem("lost", kind, "%s %s: %s %r" % (method, path[:80], k, e))
        return None
    ms = (time.perf_counter() - t) * 1000
    stats.add(kind, status, ms)
    if status == 503 and ("retry-after" in h or b"busy" in data[:200]):
        with stats.lock:
            stats.deliberate_503 += 1
    elif status >= 500:
        stats.problem("5xx", kind, "%s %s -> %d %s" % (method, path[:80], status, data[:200]))
    elif status not in expect:
        stats.problem("unexpected status", kind, "%s %s -> %d %s" % (method, path[:80], status, data[:200]))
    return status, h, data


def backoff(stop, h, rng):
    try:
        wait = min(2.0, float(h.get("retry-after", "1")))
    except ValueError:
        wait = 1.0
    stop.wait(wait * rng.uniform(0.5, 1.0))


def check_found(frame, data):
    """(right?, found ids, mode) for a recognition answer."""
    try:
        j = json.loads(data)
        ids = [f["id"] for f in j["found"]]
        mode = j.get("mode")
    except (ValueError, KeyError, TypeError):
        return False, None, None
    want = [frame["expected"]] if frame["expected"] else []
    return ids == want, ids, mode


# ---------------------------------------------------------------- clients

def recognition_client(k, port, frames, stats, stop, args):
    rng = random.Random(args.seed * 1000 + k)
    c = Client(port, args.timeout)
    groups = {}
    for f in frames:
        groups.setdefault(f["expected"], []).append(f)
    keys = sorted(groups, key=lambda x: x or "")
    while not stop.is_set():
        # A visitor looks at one exhibit (or at a wall) for a few frames.
        g = None if (None in groups and rng.random() < 0.15) else rng.choice([x for x in keys if x])
        prev = ""
        for _ in range(rng.randint(3, 8)):
            if stop.is_set():
                break
            frame = rng.choice(groups[g])
            path = "/api/recognize" + ("?prev=" + urllib.parse.quote(prev) if prev else "")
            if rng.random() < 0.1:
                body, ctype = multipart({"image": frame["body"]})
            else:
                body, ctype = frame["body"], "image/jpeg"
            r = call(stats, c, "recognize", "POST", path, body, {"Content-Type": ctype})
            if r is None:
                stop.wait(0.5)
                continue
            status, h, data = r
            if status == 503:
                backoff(stop, h, rng)
                continue
            if status == 200:
                right, ids, mode = check_found(frame, data)
                if not right:
                    stats.problem("wrong recognition", "recognize",
                                  {"frame": frame["name"], "expected": frame["expected"], "found": ids,
                                   "mode": mode, "prev": prev})
                prev = ",".join(ids[:20])  # as the web client: every exhibit of the last answer
            stop.wait(rng.uniform(0.02, 0.2))  # the phone draws the answer, grabs the next frame
    with stats.lock:
        stats.retries += c.retries


def reader_client(k, port, stats, stop, args):
    rng = random.Random(args.seed * 2000 + k)
    c = Client(port, args.timeout)
    ids = [e[0] for e in EXHIBITS]
    etags = {}
    while not stop.is_set():
        x = rng.random()
        eid = rng.choice(ids)
        if x < 0.15:
            r = call(stats, c, "exhibits_list", "GET", "/api/exhibits")
            if r and r[0] == 200:
                try:
                    got = {e["id"] for e in json.loads(r[2])["exhibits"]}
                    if not set(ids) <= got:
                        stats.problem("bad answer", "exhibits_list", "missing %s" % sorted(set(ids) - got))
                except (ValueError, KeyError, TypeError) as e:
                    stats.problem("bad answer", "exhibits_list", repr(e))
        elif x < 0.35:
            unknown = rng.random() < 0.05
            path = "/api/exhibits/" + ("no-such-exhibit" if unknown else eid)
            r = call(stats, c, "exhibit_get", "GET", path, expect=(404,) if unknown else (200,))
            if r and r[0] == 200:
                try:
                    if json.loads(r[2])["id"] != eid:
                        stats.problem("bad answer", "exhibit_get", r[2][:200])
                except (ValueError, KeyError, TypeError) as e:
                    stats.problem("bad answer", "exhibit_get", repr(e))
        elif x < 0.85:
            n = rng.choice(THUMBS)
            path = "/api/exhibits/%s/image?thumb=%d" % (eid, n)
            hdr, expect = {}, (200,)
            if path in etags and rng.random() < 0.3:
                hdr, expect = {"If-None-Match": etags[path]}, (304,)
            r = call(stats, c, "exhibit_thumb", "GET", path, headers=hdr, expect=expect)
            if r and r[0] == 200:
                if "etag" in r[1]:
                    etags[path] = r[1]["etag"]
                size = jpeg_size(r[2]) if r[1].get("content-type") == "image/jpeg" else None
                if size is None or max(size) > n:  # (originals at most n px come back as they are)
                    stats.problem("bad answer", "exhibit_thumb", "%s: %s %s" % (path, r[1].get("content-type"), size))
        else:
            r = call(stats, c, "exhibit_image", "GET", "/api/exhibits/%s/image" % eid)
            if r and r[0] == 200 and not r[2].startswith(b"\xff\xd8"):
                stats.problem("bad answer", "exhibit_image", "not a JPEG")
        if r and r[0] == 503:
            backoff(stop, r[1], rng)
        stop.wait(rng.uniform(0.1, 0.6))
    with stats.lock:
        stats.retries += c.retries


def admin_client(k, port, stats, stop, args, temp_image, t_end):
    rng = random.Random(args.seed * 3000 + k)
    c = Client(port, args.timeout)
    auth = {"Authorization": "Bearer " + TOKEN}
    n = 0
    next_add = time.monotonic() + rng.uniform(3, args.add_every)
    added = []
    while not stop.is_set():
        n += 1
        eid, _, title, artist, year = rng.choice(EXHIBITS)
        meta = {"soak": n, "client": k, "room": rng.choice(["A", "B", "C"]), "width_m": 0.5 + rng.random()}
        body = json.dumps({"title": "%s (%d)" % (title, n), "artist": artist, "year": year,
                           "url": "https://example.org/%s?v=%d" % (eid, n), "meta": meta}).encode()
        r = call(stats, c, "admin_put", "PUT", "/api/exhibits/" + eid, body,
                 dict(auth, **{"Content-Type": "application/json"}))
        if r and r[0] == 200:
            try:
                j = json.loads(r[2])
                if j["id"] != eid or j["title"] != "%s (%d)" % (title, n) or j["meta"].get("soak") != n:
                    stats.problem("bad answer", "admin_put", r[2][:200])
            except (ValueError, KeyError, TypeError, AttributeError) as e:
                stats.problem("bad answer", "admin_put", repr(e))
        elif r and r[0] == 503:
            backoff(stop, r[1], rng)
        if rng.random() < 0.2:  # the admin page's quality report (computed once per exhibit, then kept)
            qid = rng.choice(EXHIBITS)[0]
            r = call(stats, c, "admin_quality", "GET", "/api/exhibits/%s/quality" % qid, headers=auth)
            if r and r[0] == 200:
                try:
                    q = json.loads(r[2])
                    if not (isinstance(q.get("score"), int) and q.get("id") == qid):
                        stats.problem("bad answer", "admin_quality", r[2][:200])
                except ValueError as e:
                    stats.problem("bad answer", "admin_quality", repr(e))
        # Now and then a new exhibit, read back, then deleted (not in the last 10 s).
        if time.monotonic() >= next_add and time.monotonic() < t_end - 10:
            next_add = time.monotonic() + args.add_every * rng.uniform(0.5, 1.5)
            tid = "soak-tmp-%d-%d" % (k, n)
            body, ctype = multipart({"image": temp_image, "id": tid, "title": "Temporary %d" % n,
                                     "artist": "Soak", "year": "2024", "url": "https://example.org/" + tid,
                                     "meta": json.dumps({"soak": n})})
            r = call(stats, c, "admin_add", "POST", "/api/exhibits", body, dict(auth, **{"Content-Type": ctype}),
                     expect=(201,), fresh=True)  # not retried: not idempotent
            if r and r[0] == 201:
                added.append(tid)
                call(stats, c, "admin_verify", "GET", "/api/exhibits/" + tid)
                stop.wait(rng.uniform(0.5, 3))
                r = call(stats, c, "admin_delete", "DELETE", "/api/exhibits/" + tid, headers=auth, expect=(204,))
                if r and r[0] == 204:
                    added.remove(tid)
                    call(stats, c, "admin_verify", "GET", "/api/exhibits/" + tid, expect=(404,))
        stop.wait(rng.uniform(0.5, 2.0))
    for tid in added:  # leave the database as it was
        call(stats, c, "admin_delete", "DELETE", "/api/exhibits/" + tid, headers=auth, expect=(204,))
    with stats.lock:
        stats.retries += c.retries


class SlowTally:
    def __init__(self):
        self.lock = threading.Lock()
        self.opened = self.abandoned = self.reset_by_us = self.closed_by_server = self.connect_failed = 0
        self.server_close_after_s = []
        self.answers = {}


def slow_request(rng):
    """(sent at once, trickled): a request's headers trickled, or a POST whose body trickles."""
    if rng.random() < 0.5:
        return b"", (b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nUser-Agent: soak-slow\r\nX-Pad: " + b"a" * 200
                     + b"\r\n\r\n")
    body_len = 20000
    head = ("POST /api/recognize HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: image/jpeg\r\n"
            "Content-Length: %d\r\n\r\n" % body_len).encode()
    return head, b"\xff\xd8" + bytes(body_len - 2)


def slow_socket(port, stop, tally, rng, life_s, interval, stats=None, keep_open=None):
    """One slow connection: trickle a byte every `interval()` s for `life_s` s
    (or, with keep_open, until keep_open is set), unless the server closes it
    first. Returns when done."""
    try:
        s = socket.create_connection((HOST, port), timeout=10)
    except OSError:
        with tally.lock:
            tally.connect_failed += 1
        stop.wait(1)
        return
    with tally.lock:
        tally.opened += 1
    t0 = time.monotonic()
    head, payload = slow_request(rng)
    i, closed, answer = 0, False, b""
    if head:
        try:
            s.sendall(head)
        except OSError:
            payload = b""
    next_send = time.monotonic()
    try:
        while not stop.is_set():
            now = time.monotonic()
            if keep_open is None and now - t0 >= life_s:
                break
            if keep_open is not None and keep_open.is_set():
                break
            if now >= next_send and i < len(payload):
                try:
                    s.send(payload[i:i + 1])
                    i += 1
                except OSError:
                    closed = True
                    try:  # an answer the server sent before closing
                        s.settimeout(0.5)
                        answer += s.recv(65536)
                    except OSError:
                        pass
                    break
                next_send = now + interval()
            rd, _, _ = select.select([s], [], [], 0.25)
            if rd:
                try:
                    part = s.recv(65536)
                except OSError:
                    part = b""
                if not part:
                    closed = True
                    break
                answer += part
    finally:
        if closed:
            with tally.lock:
                tally.closed_by_server += 1
                tally.server_close_after_s.append(time.monotonic() - t0)
        else:
            with tally.lock:
                tally.abandoned += 1
            if rng.random() < 0.5:  # half abandoned with a reset
                s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                with tally.lock:
                    tally.reset_by_us += 1
        s.close()
    if answer.startswith(b"HTTP/"):
        try:
            status = int(answer.split(b" ", 2)[1])
        except (ValueError, IndexError):
            status = "garbled"
        with tally.lock:
            tally.answers[str(status)] = tally.answers.get(str(status), 0) + 1
        if stats is not None and isinstance(status, int):
            stats.add("slow_socket", status, 0)
            if status >= 500 and status != 503:
                stats.problem("5xx", "slow_socket", answer[:200].decode("latin-1"))


def slow_client(k, port, stats, stop, tally, args):
    rng = random.Random(args.seed * 4000 + k)
    while not stop.is_set():
        slow_socket(port, stop, tally, rng, rng.uniform(3, 45), lambda: rng.uniform(1.5, 4), stats)


# ---------------------------------------------------------------- sampling

def rss_kb(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


def fd_counts(pid):
    """(total, sockets, others) open descriptors of pid, or None."""
    try:
        names = os.listdir("/proc/%d/fd" % pid)
    except OSError:
        return None
    sockets = 0
    for n in names:
        try:
            if os.readlink("/proc/%d/fd/%s" % (pid, n)).startswith("socket:"):
                sockets += 1
        except OSError:
            pass
    return len(names), sockets, len(names) - sockets


def fd_targets(pid):
    """Non-socket descriptors of pid by what they point at (for the report)."""
    out = {}
    try:
        for n in os.listdir("/proc/%d/fd" % pid):
            try:
                t = os.readlink("/proc/%d/fd/%s" % (pid, n))
            except OSError:
                continue
            if not t.startswith("socket:"):
                t = "pipe" if t.startswith("pipe:") else t
                out[t] = out.get(t, 0) + 1
    except OSError:
        pass
    return out


def sampler(proc, stop, samples, t0, every):
    """The server's RSS and descriptors every `every` s (on schedule, whatever the server does)."""
    while not stop.is_set():
        t = time.monotonic() - t0
        if proc.poll() is not None:
            samples.append({"t": round(t, 1), "rss_mb": None, "fds": None, "died": proc.returncode})
            stop.set()
            return
        rss = rss_kb(proc.pid)
        fds = fd_counts(proc.pid)
        samples.append({"t": round(t, 1), "rss_mb": round(rss / 1024, 1) if rss else None,
                        "fds": fds[0] if fds else None, "sockets": fds[1] if fds else None,
                        "other_fds": fds[2] if fds else None})
        stop.wait(every - (time.monotonic() - t0 - t))


def prober(port, stats, stop, every, timeout, probes):
    """GET /healthz on a fresh connection every `every` s, as a load balancer would."""
    c = Client(port, timeout)
    while not stop.is_set():
        t = time.perf_counter()
        r = call(stats, c, "healthz", "GET", "/healthz", fresh=True)
        ms = (time.perf_counter() - t) * 1000
        probes.append(round(ms, 1) if r else None)
        stop.wait(max(0.0, every - ms / 1000))


# ---------------------------------------------------------------- phases

def preflight(port, frames, stats, temp_image):
    """Keeps the frames recognised right three times over; returns (kept, dropped)."""
    c = Client(port, 120)
    auth = {"Authorization": "Bearer " + TOKEN}
    body, ctype = multipart({"image": temp_image, "id": "soak-preflight", "title": "Preflight",
                             "url": "https://example.org/x", "meta": "{}"})
    r = call(stats, c, "admin_add", "POST", "/api/exhibits", body, dict(auth, **{"Content-Type": ctype}),
             expect=(201,), fresh=True)
    if not r or r[0] != 201:
        sys.exit("soak: preflight: adding an exhibit failed: %s" % (r and r[:1] + (r[2][:300],)))
    kept, dropped = [], []
    others = [e[0] for e in EXHIBITS]
    for f in frames:
        prevs = ["", f["expected"] or others[0], "soak-preflight"]
        ok = True
        for prev in prevs:
            path = "/api/recognize" + ("?prev=" + prev if prev else "")
            r = call(stats, c, "preflight", "POST", path, f["body"], {"Content-Type": "image/jpeg"})
            if not r or r[0] != 200 or not check_found(f, r[2])[0]:
                ok = False
                break
        (kept if ok else dropped).append(f)
    r = call(stats, c, "admin_delete", "DELETE", "/api/exhibits/soak-preflight", headers=auth, expect=(204,))
    if not r or r[0] != 204:
        sys.exit("soak: preflight: deleting the exhibit failed")
    return kept, dropped


def slow_p99_phase(port, frames, stats, args):
    """Recognition latency of one sequential client, alone and with 8 slow sockets open."""
    positives = [f for f in frames if f["expected"]]
    rng = random.Random(args.seed * 5000)
    lat = {"idle": [], "slow": []}
    statuses = {"idle": {}, "slow": {}}
    tally = SlowTally()
    c = Client(port, args.timeout)
    blocks = []
    for rnd in range(args.p99_rounds):
        for mode in ("idle", "slow"):
            hold, holders = threading.Event(), []
            never = threading.Event()
            if mode == "slow":
                def holder(j):
                    r2 = random.Random(args.seed * 6000 + rnd * 100 + j)
                    while not hold.is_set():  # reopened whenever the server closes it
                        slow_socket(port, never, tally, r2, 0, lambda: r2.uniform(1.5, 2.5), stats, keep_open=hold)
                holders = [threading.Thread(target=holder, args=(j,), daemon=True) for j in range(args.slow_sockets)]
                for h in holders:
                    h.start()
                time.sleep(3)  # accepted, each in its request
            t_block = time.monotonic()
            n = 0
            while n < args.p99_requests and time.monotonic() - t_block < args.p99_max_block_s:
                f = positives[rng.randrange(len(positives))]
                t = time.perf_counter()
                r = call(stats, c, "p99_" + mode, "POST", "/api/recognize", f["body"], {"Content-Type": "image/jpeg"},
                         fresh=True)
                ms = (time.perf_counter() - t) * 1000
                n += 1
                key = str(r[0]) if r else "lost"
                statuses[mode][key] = statuses[mode].get(key, 0) + 1
                if r and r[0] == 200:
                    lat[mode].append(ms)
                    right, ids, m = check_found(f, r[2])
                    if not right:
                        stats.problem("wrong recognition", "p99_" + mode,
                                      {"frame": f["name"], "expected": f["expected"], "found": ids, "mode": m})
            blocks.append({"round": rnd, "mode": mode, "requests": n, "seconds": round(time.monotonic() - t_block, 1),
                           "p50_ms": r1(pct(lat[mode][-n:], 50)) if n else None})
            if mode == "slow":
                hold.set()
                for h in holders:
                    h.join(timeout=15)
                time.sleep(2)
    p99 = {m: pct(v, 99) for m, v in lat.items()}
    ratio = p99["slow"] / p99["idle"] if p99["idle"] and p99["slow"] else None
    return {
        "slow_sockets": args.slow_sockets, "rounds": args.p99_rounds, "requests_per_block": args.p99_requests,
        "max_block_s": args.p99_max_block_s,
        "idle": {"n": len(lat["idle"]), "p50_ms": r1(pct(lat["idle"], 50)), "p99_ms": r1(p99["idle"]),
                 "statuses": statuses["idle"]},
        "slow": {"n": len(lat["slow"]), "p50_ms": r1(pct(lat["slow"], 50)), "p99_ms": r1(p99["slow"]),
                 "statuses": statuses["slow"]},
        "ratio_p99": round(ratio, 2) if ratio else None, "goal_ratio": 2.0,
        "goal_met": ratio is not None and ratio <= 2.0 and not statuses["slow"].get("lost"),
        "blocks": blocks,
        "slow_socket_tally": {"opened": tally.opened, "closed_by_server": tally.closed_by_server,
                              "server_answers": tally.answers},
    }


def parse_server_log(path):
    routes, events, other = {}, {}, []
    with open(path, errors="replace") as f:
        for line in f:
            try:
                j = json.loads(line)
            except ValueError:
                if len(other) < 50:
                    other.append(line.rstrip()[:300])
                continue
            if "event" in j:
                events[j["event"]] = events.get(j["event"], 0) + 1
                if j["event"] not in ("listening", "reloaded", "stopped") and len(other) < 50:
                    other.append(line.rstrip()[:300])
            elif "route" in j:
                k = "%s %s" % (j.get("method"), j["route"])
                d = routes.setdefault(k, {})
                d[str(j.get("status"))] = d.get(str(j.get("status")), 0) + 1
    return {"requests_by_route": routes, "events": events, "other_lines": other}


# ---------------------------------------------------------------- main

def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mvkp", default="build/mvkp")
    ap.add_argument("--out", default="out/soak")
    ap.add_argument("--samples", default=os.path.join(here, "..", "samples"))
    ap.add_argument("--seconds", type=float, default=600)
    ap.add_argument("--clients", type=int, default=32, help="recognition + readers + admin + slow sockets")
    ap.add_argument("--slow-clients", type=int, default=-1, help="slow sockets among the clients (-1: clients/8)")
    ap.add_argument("--no-keep-alive", action="store_true",
                    help="clients close each connection after one request (default: keep-alive, as browsers)")
    ap.add_argument("--warmup-frac", type=float, default=0.2)
    ap.add_argument("--sample-s", type=float, default=3)
    ap.add_argument("--timeout", type=float, default=60, help="client timeout per request, s")
    ap.add_argument("--views", type=int, default=6, help="query frames per exhibit")
    ap.add_argument("--add-every", type=float, default=45, help="mean seconds between an admin client's adds")
    ap.add_argument("--rss-check", choices=["growth", "bound"], default="growth")
    ap.add_argument("--rss-growth-pct", type=float, default=5)
    ap.add_argument("--rss-limit-mb", type=float, default=1024)
    ap.add_argument("--fd-margin", type=int, default=0, help="descriptors above the median allowed (0: auto)")
    ap.add_argument("--slow-sockets", type=int, default=8, help="slow sockets of the latency phase")
    ap.add_argument("--p99-rounds", type=int, default=3)
    ap.add_argument("--p99-requests", type=int, default=100, help="sequential recognitions per block")
    ap.add_argument("--p99-max-block-s", type=float, default=90)
    ap.add_argument("--fail-on-slow-ratio", action="store_true", help="the slow-socket ratio > 2 fails the run")
    ap.add_argument("--seed", type=int, default=19)
    ap.add_argument("--server-arg", action="append", default=[], help="extra `mvkp serve` argument (repeatable)")
    ap.add_argument("--server-env", action="append", default=[], metavar="NAME=VALUE",
                    help="environment variable for the server (repeatable), e.g. MALLOC_ARENA_MAX=2")
    args = ap.parse_args()

    Client.close_each = args.no_keep_alive
    out = os.path.abspath(args.out)
    work = os.path.join(out, "work")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(work)
    samples = os.path.abspath(args.samples)
    mvkp = os.path.join(work, "mvkp")
    copy_binary(args.mvkp, mvkp)
    with open(mvkp, "rb") as f:
        binary = {"path": os.path.abspath(args.mvkp), "sha256": hashlib.sha256(f.read()).hexdigest()[:16],
                  "mtime": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(os.stat(args.mvkp).st_mtime))}

    n_slow = max(1, round(args.clients / 8)) if args.slow_clients < 0 else args.slow_clients
    n_admin = max(1, args.clients // 16)
    n_read = max(1, round(args.clients / 4))
    n_rec = args.clients - n_slow - n_admin - n_read
    if n_rec < 1:
        sys.exit("soak: --clients too small (at least 4)")

    log("setup in %s (binary %s, %s)" % (work, binary["sha256"], binary["mtime"]))
    db, token_file, frames, temp_image = make_setup(mvkp, samples, work, args.views, args.seed)
    server_log = os.path.join(out, "server.log")
    proc, port, listening, cmd = start_server(mvkp, db, token_file, server_log, args.server_arg, args.server_env)
    log("server pid %d on port %d: %s" % (proc.pid, port, json.dumps(listening)))
    t0 = time.monotonic()
    stats = Stats(t0)
    checks = []
    report = {"issue": 19, "binary": binary, "server_cmd": cmd[1:], "server_env": args.server_env,
              "listening": listening,
              "seconds": args.seconds, "keep_alive": not args.no_keep_alive,
              "clients": {"total": args.clients, "recognition": n_rec, "readers": n_read,
                                                   "admin": n_admin, "slow_sockets": n_slow}}
    try:
        kept, dropped = preflight(port, frames, stats, temp_image)
        log("preflight: %d frames kept, %d dropped (not right every time when idle): %s"
            % (len(kept), len(dropped), [f["name"] for f in dropped]))
        report["frames"] = {"kept": len(kept), "dropped": [f["name"] for f in dropped],
                            "with_exhibit": sum(1 for f in kept if f["expected"]),
                            "without_exhibit": sum(1 for f in kept if not f["expected"])}
        if not any(f["expected"] for f in kept):
            sys.exit("soak: no frame is recognised even when idle")
        time.sleep(1)
        idle_fds = fd_counts(proc.pid)
        idle_targets = fd_targets(proc.pid)
        idle_rss = rss_kb(proc.pid)
        pre_stats = {k: dict(v) for k, v in stats.status.items()}
        pre_problems = dict(stats.nbad)

        # ---- the soak
        log("soak: %d clients (%d recognition, %d readers, %d admin, %d slow sockets) for %.0f s"
            % (args.clients, n_rec, n_read, n_admin, n_slow, args.seconds))
        stats = Stats(time.monotonic())
        stop = threading.Event()
        tally = SlowTally()
        samples = []
        ts = time.monotonic()
        t_end = ts + args.seconds
        probes = []
        threads = [threading.Thread(target=sampler, args=(proc, stop, samples, ts, args.sample_s), daemon=True),
                   threading.Thread(target=prober, args=(port, stats, stop, args.sample_s, args.timeout, probes),
                                    daemon=True)]
        threads += [threading.Thread(target=recognition_client, args=(k, port, kept, stats, stop, args), daemon=True)
                    for k in range(n_rec)]
        threads += [threading.Thread(target=reader_client, args=(k, port, stats, stop, args), daemon=True)
                    for k in range(n_read)]
        threads += [threading.Thread(target=admin_client, args=(k, port, stats, stop, args, temp_image, t_end),
                                     daemon=True) for k in range(n_admin)]
        threads += [threading.Thread(target=slow_client, args=(k, port, stats, stop, tally, args), daemon=True)
                    for k in range(n_slow)]
        for th in threads:
            th.start()
        last_note = ts
        while not stop.is_set() and time.monotonic() < t_end:
            stop.wait(min(1.0, max(0.0, t_end - time.monotonic())))
            if time.monotonic() - last_note >= 60:
                last_note = time.monotonic()
                s = samples[-1] if samples else {}
                with stats.lock:
                    nreq = sum(sum(v.values()) for v in stats.status.values())
                    nbad = dict(stats.nbad)
                log("  t=%3.0f s: %d requests, RSS %s MB, %s fds, problems %s"
                    % (last_note - ts, nreq, s.get("rss_mb"), s.get("fds"), nbad or "none"))
        elapsed = time.monotonic() - ts
        stop.set()
        for th in threads:
            th.join(timeout=args.timeout + 10)
        alive_threads = sum(1 for th in threads if th.is_alive())
        # Descriptors once the load is gone (keep-alive 1 s, slow sockets closed).
        drained = None
        for _ in range(30):
            time.sleep(1)
            drained = fd_counts(proc.pid)
            if drained and idle_fds and drained[1] <= idle_fds[1] + 1:
                break
        drained_targets = fd_targets(proc.pid)
        drained_rss = rss_kb(proc.pid)
        soak_stats = stats

        # ---- the slow-socket latency phase
        if proc.poll() is None:
            log("slow-socket phase: %d rounds of %d sequential recognitions, idle then with %d slow sockets"
                % (args.p99_rounds, args.p99_requests, args.slow_sockets))
            phase_stats = Stats(time.monotonic())
            phase = slow_p99_phase(port, kept, phase_stats, args)
            log("  recognition p99 idle %s ms, with %d slow sockets %s ms: ratio %s (goal <= 2)"
                % (phase["idle"]["p99_ms"], args.slow_sockets, phase["slow"]["p99_ms"], phase["ratio_p99"]))
        else:
            phase, phase_stats = None, Stats(time.monotonic())
    finally:
        rc = None
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                rc = proc.wait(timeout=40)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                rc = "killed after 40 s"
        else:
            rc = "died: %s" % proc.returncode

    # ---------------------------------------------------------------- report
    st = soak_stats
    kinds = {}
    for kind, d in sorted(st.status.items()):
        lat = st.lat.get(kind, [])
        kinds[kind] = {"requests": sum(d.values()), "statuses": d,
                       "ok": sum(v for s, v in d.items() if s.isdigit() and (200 <= int(s) < 300 or s == "304")),
                       "p50_ms": r1(pct(lat, 50)), "p99_ms": r1(pct(lat, 99)), "max_ms": r1(max(lat) if lat else None)}
    warm_t = args.warmup_frac * elapsed
    post = [s for s in samples if s["t"] >= warm_t and s.get("rss_mb")]
    rss_first = post[0]["rss_mb"] if post else None
    rss_last = post[-1]["rss_mb"] if post else None
    # The growth compares the medians of the first and the last tenth of the
    # post-warm-up samples (at least 3 each), so that the allocator's swings
    # between two samples (admin adds train and reload) do not decide.
    win = max(3, len(post) // 10)
    rss_first_m = statistics.median([s["rss_mb"] for s in post[:win]]) if post else None
    rss_last_m = statistics.median([s["rss_mb"] for s in post[-win:]]) if post else None
    growth = 100.0 * (rss_last_m - rss_first_m) / rss_first_m if post else None
    # For reading a failure: still climbing at the end (a leak) or levelling off (warm-up)?
    rss_slope = slope_per_min([(x["t"], x["rss_mb"]) for x in post])
    rss_slope_2nd = slope_per_min([(x["t"], x["rss_mb"]) for x in post if x["t"] >= elapsed / 2])
    rss_peak = max((s["rss_mb"] for s in samples if s.get("rss_mb")), default=None)
    fd_post = [s["fds"] for s in post if s.get("fds") is not None]
    other_post = [s["other_fds"] for s in post if s.get("other_fds") is not None]
    fd_median = statistics.median(fd_post) if fd_post else None
    fd_last = fd_post[-1] if fd_post else None
    margin = args.fd_margin or max(5, math.ceil(0.1 * (fd_median or 0)))
    healthz = [x for x in probes if x is not None]

    def check(name, ok, detail):
        checks.append({"check": name, "ok": bool(ok), "detail": detail})

    died = [x for x in samples if "died" in x]
    check("server alive through the run and stopped cleanly on SIGTERM", not died and rc == 0,
          "exit status %s%s" % (rc, "; died during the soak" if died else ""))
    n5 = st.nbad.get("5xx", 0) + phase_stats.nbad.get("5xx", 0) + pre_problems.get("5xx", 0)
    check("no 5xx other than deliberate 503s", n5 == 0, "%d 5xx, %d deliberate 503s" % (n5, st.deliberate_503))
    lost = st.nbad.get("lost", 0)
    check("no request lost by a regular client (timeouts, resets)", lost == 0,
          "%d lost (client timeout %.0f s), %d stale keep-alive retries" % (lost, args.timeout, st.retries))
    wrong = st.nbad.get("wrong recognition", 0) + phase_stats.nbad.get("wrong recognition", 0)
    nrec = kinds.get("recognize", {}).get("ok", 0)
    check("no wrong recognition", wrong == 0 and nrec > 0, "%d wrong of %d answered recognitions" % (wrong, nrec))
    nodd = st.nbad.get("unexpected status", 0) + st.nbad.get("bad answer", 0)
    check("no unexpected status or malformed answer", nodd == 0, "%d" % nodd)
    if args.rss_check == "growth":
        check("RSS growth <= %g %% after the warm-up" % args.rss_growth_pct,
              growth is not None and len(post) >= 3 and growth <= args.rss_growth_pct,
              "%s -> %s MB; medians of the first and last %d samples %s -> %s MB: %s %%"
              % (rss_first, rss_last, win, rss_first_m, rss_last_m, r1(growth)))
    else:
        # short runs: growth over a few seconds means nothing; only a bound
        check("RSS stays under %g MB (short run: no growth check)" % args.rss_limit_mb,
              rss_peak is not None and rss_peak <= args.rss_limit_mb, "peak %s MB" % rss_peak)
    # Descriptors: the total at the end of the load within a margin of the
    # post-warm-up median; the non-socket ones (database files: SQLite keeps
    # a closed connection's descriptor while another holds a lock on the file,
    # and reuses it, so a few more after the first writes are no leak) flat;
    # and once the load is gone, no more sockets than when idle (+1).
    other_med = statistics.median(other_post) if other_post else None
    check("descriptors flat",
          fd_last is not None and fd_last <= fd_median + margin and other_post[-1] <= other_med + 2
          and drained is not None and idle_fds is not None and drained[1] <= idle_fds[1] + 1
          and drained[2] <= max(other_post) + 1,
          "post-warm-up median %s, last %s (margin %d); non-socket: median %s, last %s; idle before: %s "
          "(%s sockets), after the load: %s (%s sockets)"
          % (fd_median, fd_last, margin, other_med, other_post[-1] if other_post else None,
             idle_fds and idle_fds[0], idle_fds and idle_fds[1], drained and drained[0], drained and drained[1]))
    if alive_threads:
        check("clients finished", False, "%d client threads still blocked" % alive_threads)
    if phase is not None:
        if args.fail_on_slow_ratio:
            check("recognition p99 with %d slow sockets <= 2x idle" % args.slow_sockets, phase["goal_met"],
                  "ratio %s" % phase["ratio_p99"])
    else:
        check("slow-socket phase ran", False, "server gone")

    passed = all(c["ok"] for c in checks)
    report.update({
        "elapsed_s": round(elapsed, 1), "warmup_s": round(warm_t, 1), "preflight_statuses": pre_stats,
        "preflight_problems": pre_problems,
        "kinds": kinds, "deliberate_503": st.deliberate_503, "keepalive_retries": st.retries,
        "problems": st.nbad, "problem_samples": st.bad[:100],
        "rss_mb": {"idle": r1(idle_rss / 1024) if idle_rss else None, "first_after_warmup": rss_first,
                   "last": rss_last, "first_window_median": rss_first_m, "last_window_median": rss_last_m,
                   "growth_pct": r1(growth), "growth_window_samples": win, "peak": rss_peak,
                   "slope_mb_per_min_after_warmup": r1(rss_slope), "slope_mb_per_min_second_half": r1(rss_slope_2nd),
                   "after_load": r1(drained_rss / 1024) if drained_rss else None},
        "fds": {"idle": idle_fds and idle_fds[0], "post_warmup_median": fd_median, "last": fd_last,
                "max": max(fd_post) if fd_post else None, "margin": margin, "after_load": drained and drained[0],
                "sockets_idle": idle_fds and idle_fds[1], "sockets_after_load": drained and drained[1],
                "non_socket_idle": idle_targets, "non_socket_after_load": drained_targets},
        "healthz_ms": {"n": len(probes), "answered": len(healthz), "p50": r1(pct(healthz, 50)),
                       "p99": r1(pct(healthz, 99)), "max": r1(max(healthz) if healthz else None),
                       "over_100ms": sum(1 for x in healthz if x > 100)},
        "slow_sockets": {"opened": tally.opened, "abandoned": tally.abandoned, "reset_by_us": tally.reset_by_us,
                         "closed_by_server": tally.closed_by_server, "connect_failed": tally.connect_failed,
                         "server_close_after_s": {"p50": r1(pct(tally.server_close_after_s, 50)),
                                                  "max": r1(max(tally.server_close_after_s, default=0))},
                         "answers": tally.answers},
        "slow_socket_phase": phase, "slow_phase_problems": phase_stats.nbad,
        "slow_phase_problem_samples": phase_stats.bad[:20],
        "samples": samples, "server_exit": rc, "server_log": parse_server_log(server_log),
        "checks": checks, "passed": passed,
    })
    with open(os.path.join(out, "report.json"), "w") as f:
        json.dump(report, f, indent=1)
    text = summary(report)
    with open(os.path.join(out, "summary.txt"), "w") as f:
        f.write(text)
    print(text, end="")
    log("report: %s/report.json, %s/summary.txt" % (out, out))
    return 0 if passed else 1


def summary(r):
    L = []
    c = r["clients"]
    L.append("mvkp soak (issue 19): %.0f s, %d clients = %d recognition, %d readers, %d admin, %d slow sockets (%s)"
             % (r["elapsed_s"], c["total"], c["recognition"], c["readers"], c["admin"], c["slow_sockets"],
                "keep-alive" if r["keep_alive"] else "a connection per request"))
    cmd = r["server_env"] + r["server_cmd"][:1] + ["DB"] + r["server_cmd"][2:]
    L.append("server: %s (binary %s of %s)" % (" ".join(cmd), r["binary"]["sha256"], r["binary"]["mtime"]))
    L.append("frames: %d with an exhibit, %d without (%d dropped by the preflight)"
             % (r["frames"]["with_exhibit"], r["frames"]["without_exhibit"], len(r["frames"]["dropped"])))
    L.append("")
    L.append("%-16s %8s %8s %6s %8s %8s %8s  statuses" % ("kind", "requests", "ok", "503", "p50 ms", "p99 ms",
                                                          "max ms"))
    for k, v in r["kinds"].items():
        L.append("%-16s %8d %8d %6d %8s %8s %8s  %s" % (k, v["requests"], v["ok"], v["statuses"].get("503", 0),
                                                       v["p50_ms"], v["p99_ms"], v["max_ms"],
                                                       json.dumps(v["statuses"], sort_keys=True)))
    L.append("problems: %s (deliberate 503s: %d, stale keep-alive retries: %d)"
             % (json.dumps(r["problems"]) if r["problems"] else "none", r["deliberate_503"], r["keepalive_retries"]))
    m = r["rss_mb"]
    L.append("RSS MB: idle %s, first after warm-up (t >= %.0f s) %s, last %s, growth %s %% (medians of the first and "
             "last %d samples %s -> %s), peak %s, after the load %s; trend %s MB/min after the warm-up, %s MB/min "
             "in the second half" % (m["idle"], r["warmup_s"], m["first_after_warmup"], m["last"], m["growth_pct"],
                                     m["growth_window_samples"], m["first_window_median"], m["last_window_median"],
                                     m["peak"], m["after_load"], m["slope_mb_per_min_after_warmup"],
                                     m["slope_mb_per_min_second_half"]))
    d = r["fds"]
    L.append("descriptors: idle %s (%s sockets), post-warm-up median %s, max %s, last %s, after the load %s (%s sockets)"
             % (d["idle"], d["sockets_idle"], d["post_warmup_median"], d["max"], d["last"], d["after_load"],
                d["sockets_after_load"]))
    h = r["healthz_ms"]
    L.append("/healthz probes (fresh connection every few s): %d, %d answered, p50 %s ms, p99 %s ms, max %s ms, "
             "%d over 100 ms" % (h["n"], h["answered"], h["p50"], h["p99"], h["max"], h["over_100ms"]))
    s = r["slow_sockets"]
    L.append("slow sockets: %d opened, %d abandoned by us (%d with a reset), %d closed by the server (median after "
             "%s s, max %s s), answers %s" % (s["opened"], s["abandoned"], s["reset_by_us"], s["closed_by_server"],
                                             s["server_close_after_s"]["p50"], s["server_close_after_s"]["max"],
                                             json.dumps(s["answers"], sort_keys=True)))
    ev = r["server_log"]["events"]
    L.append("server log events: %s" % json.dumps(ev, sort_keys=True))
    L.append("RSS MB / descriptors over time:")
    sm = [x for x in r["samples"] if x.get("rss_mb")]
    step = max(1, len(sm) // 12)
    pick = sm[::step] + ([sm[-1]] if sm and sm[(len(sm) - 1) // step * step] is not sm[-1] else [])
    L.append("  " + "  ".join("t=%.0f:%s/%s" % (x["t"], x["rss_mb"], x["fds"]) for x in pick))
    p = r["slow_socket_phase"]
    L.append("")
    if p:
        L.append("slow-socket phase: recognition p99 idle %s ms (p50 %s, n %d), with %d slow sockets open %s ms "
                 "(p50 %s, n %d, statuses %s): ratio %s, goal <= 2: %s%s"
                 % (p["idle"]["p99_ms"], p["idle"]["p50_ms"], p["idle"]["n"], p["slow_sockets"], p["slow"]["p99_ms"],
                    p["slow"]["p50_ms"], p["slow"]["n"], json.dumps(p["slow"]["statuses"]), p["ratio_p99"],
                    "met" if p["goal_met"] else "NOT met",
                    "" if any("slow sockets" in c["check"] for c in r["checks"]) else " (reported, not a check)"))
    L.append("")
    for ch in r["checks"]:
        L.append("%s  %s: %s" % ("PASS" if ch["ok"] else "FAIL", ch["check"], ch["detail"]))
    L.append("soak: %s" % ("PASSED" if r["passed"] else "FAILED"))
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    sys.exit(main())
