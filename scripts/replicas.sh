#!/usr/bin/env bash
# Two `mvkp serve` replicas behind nginx (issue 7, scaling; docs/scaling.md).
#
#   scripts/replicas.sh MVKP OUTDIR [SECONDS]
#
# Installs nginx if it is missing (apt-get, sudo when not root), builds a
# database of samples/*.jpg and 42 synthetic frames of them in OUTDIR, starts
# two replicas on that one database file (admin API off, --port 0) and nginx
# in front of them (OUTDIR/nginx/nginx.conf, run with -p/-c: no root-owned
# paths, a free loopback port). Then it
#   a) gets / and /healthz through nginx,
#   b) checks that recognitions are spread over both replicas (their /metrics),
#   c) sends a 4 MB frame through nginx (200; nginx spools it to OUTDIR) and a
#      body over --max-body-mb (413 from nginx's client_max_body_size),
#   d) runs scripts/loadtest.py for SECONDS (20) against nginx, against one
#      replica with the same threads, and against one server with the pair's
#      threads, side by side, with the servers' CPU time from /proc,
#   e) kills one replica (SIGKILL) while 4 clients recognise through nginx:
#      every answer must still be 200; then restarts it and checks it rejoins,
#   f) stops every process it started on exit (trap).
# Summary on stdout and in OUTDIR/summary.json; exit 1 if a check fails.
#
# Environment: REPLICA_THREADS (1: the pair uses as many worker threads as
# a 2-core machine has), CLIENTS (16), MAX_INFLIGHT (32 per replica),
# MAX_BODY_MB (10; nginx's client_max_body_size follows it), KEEPALIVE (8
# idle upstream connections per nginx worker; 0: none), MAX_FAILS (0) and
# FAIL_TIMEOUT (5 s) of the upstream servers.
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 MVKP OUTDIR [SECONDS]" >&2
  exit 2
fi
mvkp=$(realpath "$1")
out=$(realpath -m "$2")
secs=${3:-20}
threads=${REPLICA_THREADS:-1}
clients=${CLIENTS:-16}
inflight=${MAX_INFLIGHT:-32}
body_mb=${MAX_BODY_MB:-10}
keepalive=${KEEPALIVE:-8}
max_fails=${MAX_FAILS:-0}
fail_timeout=${FAIL_TIMEOUT:-5}
here=$(cd "$(dirname "$0")" && pwd)
samples="$here/../samples"
py=/usr/bin/python3
[ -x "$py" ] || py=$(command -v python3)
log() { echo "replicas: $*"; }
for tool in "$py" curl; do
  command -v "$tool" >/dev/null || { echo "replicas: $tool is needed" >&2; exit 2; }
done

# ---- nginx -------------------------------------------------------------
nginx_bin=$(command -v nginx || true)
[ -z "$nginx_bin" ] && [ -x /usr/sbin/nginx ] && nginx_bin=/usr/sbin/nginx
if [ -z "$nginx_bin" ]; then
  log "nginx missing: apt-get install -y nginx"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get install -y nginx >/dev/null || { $sudo apt-get update >/dev/null && $sudo apt-get install -y nginx >/dev/null; }
  nginx_bin=$(command -v nginx || echo /usr/sbin/nginx)
fi
log "$("$nginx_bin" -v 2>&1)"
loadavg0=$(cat /proc/loadavg)

# ---- processes and cleanup -----------------------------------------------
declare -A rpid rport  # replica K: pid, port
nginx_pid=""
lt_pid=""    # a running loadtest.py (its child is OUT/shim.sh)
cleanup() {
  set +eu
  if [ -n "$lt_pid" ]; then
    pkill -TERM -P "$lt_pid" 2>/dev/null
    kill "$lt_pid" 2>/dev/null
  fi
  local pids="${rpid[*]} $nginx_pid"
  for p in $pids; do kill "$p" 2>/dev/null; done
  for p in $pids $lt_pid; do
    for _ in $(seq 50); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$p" 2>/dev/null
  done
  wait 2>/dev/null
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# ---- database and frames (as scripts/loadtest.sh) ------------------------
rm -rf "$out/frames" "$out/synth" "$out/big" "$out/nginx" "$out"/museum.db* "$out"/replica*.log "$out"/load-*.json \
  "$out"/load-*.out "$out"/{checks1,failover,rejoin,summary}.json "$out/shim.sh"
mkdir -p "$out/frames" "$out/synth" "$out/nginx/tmp"
db="$out/museum.db"
"$mvkp" db create "$db" >/dev/null
for f in "$samples"/*.jpg; do
  id=$(basename "$f" .jpg)
  "$mvkp" db add "$db" --id "$id" --image "$f" --title "$id" >/dev/null
  "$mvkp" synth "$f" --n 7 --seed 11 -o "$out/synth/$id" >/dev/null
  for v in "$out/synth/$id"/view_*.png; do cp "$v" "$out/frames/$id-$(basename "$v")"; done
done
# one 1800x1350 frame of ~4 MB: more than nginx keeps in memory (1 MB)
"$mvkp" synth "$samples/baboon.jpg" --n 1 --seed 1 --width 1800 --height 1350 --target-size 1000 --noise 12 \
  -o "$out/big" >/dev/null
nframes=$(find "$out/frames" -name "*.png" | wc -l)
log "database $db: $("$mvkp" db list "$db" | wc -l) lines of db list, $(du -k "$db" | cut -f1) KB; $nframes frames"

# ---- replicas -------------------------------------------------------------
# start_replica K PORT: serve the database on PORT (0: any), log to replicaK.log
start_replica() {
  local k=$1 port=$2 logf="$out/replica$1.log"
  "$mvkp" serve "$db" --host 127.0.0.1 --port "$port" --threads "$threads" --max-inflight "$inflight" \
    --max-body-mb "$body_mb" 2>>"$logf" &
  rpid[$k]=$!
  local line="" want=$(($(grep -c '"event":"listening"' "$logf" || true) + 1))
  for _ in $(seq 600); do
    # the log is appended to across restarts: wait for one more listening line
    if [ "$(grep -c '"event":"listening"' "$logf" || true)" -ge "$want" ]; then
      line=$(grep '"event":"listening"' "$logf" | tail -1)
      break
    fi
    kill -0 "${rpid[$k]}" 2>/dev/null || { cat "$logf" >&2; echo "replica $k did not start" >&2; exit 1; }
    sleep 0.1
  done
  [ -n "$line" ] || { echo "replica $k: no listening line after 60 s" >&2; exit 1; }
  rport[$k]=$(echo "$line" | "$py" -c 'import json,sys; print(json.loads(sys.stdin.read())["port"])')
}
: >"$out/replica1.log"
: >"$out/replica2.log"
start_replica 1 0
start_replica 2 0
log "replica 1: pid ${rpid[1]} port ${rport[1]}; replica 2: pid ${rpid[2]} port ${rport[2]} ($threads thread(s) each)"

# ---- nginx in front -------------------------------------------------------
free_port() { "$py" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
nport=$(free_port)
ng="$out/nginx"
ka_lines=""
if [ "$keepalive" -gt 0 ]; then
  # The server closes an idle connection after 1 s and after 2 requests
  # (each connection holds a worker): nginx drops idle ones after 500 ms.
  ka_lines="    keepalive $keepalive;
    keepalive_timeout 500ms;"
fi
cat >"$ng/nginx.conf" <<EOF
# Two mvkp serve replicas behind nginx (written by scripts/replicas.sh).
# Run: nginx -p $ng/ -c $ng/nginx.conf -e $ng/error.log
daemon off;                 # the script owns the process
worker_processes 1;         # 2 cores: the replicas need them more
pid $ng/nginx.pid;
error_log $ng/error.log warn;
events { worker_connections 1024; }
http {
    log_format upstream '\$remote_addr "\$request" \$status \$request_time '
                        'upstream=\$upstream_addr \$upstream_status \$upstream_response_time';
    access_log $ng/access.log upstream;
    client_body_temp_path $ng/tmp/body;
    proxy_temp_path $ng/tmp/proxy;
    fastcgi_temp_path $ng/tmp/fastcgi;
    uwsgi_temp_path $ng/tmp/uwsgi;
    scgi_temp_path $ng/tmp/scgi;

    upstream mvkp {
        least_conn;
        # max_fails=0: never take a replica out. nginx counts every 503 it
        # passes on as a failure (http_503 below), so with max_fails > 0 a
        # busy pair is marked down and everyone gets 502 "no live upstreams";
        # a dead replica instead costs a refused connect per request.
        server 127.0.0.1:${rport[1]} max_fails=$max_fails fail_timeout=${fail_timeout}s;
        server 127.0.0.1:${rport[2]} max_fails=$max_fails fail_timeout=${fail_timeout}s;
$ka_lines
    }
    server {
        listen 127.0.0.1:$nport;
        client_max_body_size ${body_mb}m;    # = mvkp serve --max-body-mb
        client_body_buffer_size 1m;          # frames stay in memory
        # nginx reads the whole body before it picks a replica: a slow phone
        # upload never holds a replica's worker thread.
        proxy_http_version 1.1;
        proxy_set_header Connection "";
        proxy_set_header Host \$host;
        proxy_set_header X-Forwarded-For \$proxy_add_x_forwarded_for;
        proxy_connect_timeout 2s;
        proxy_read_timeout 30s;
        proxy_next_upstream error timeout http_503;
        proxy_next_upstream_tries 2;
        proxy_next_upstream_timeout 30s;
        location = /api/recognize {
            # read-only, so safe to send again to the other replica
            proxy_next_upstream error timeout http_503 non_idempotent;
            proxy_pass http://mvkp;
        }
        location / {
            proxy_pass http://mvkp;    # /, /app.js, /healthz, /metrics, /api/exhibits...
        }
    }
}
EOF
# -e (nginx >= 1.19.5): not even the start-up error log goes to /var/log
eflag=()
"$nginx_bin" -h 2>&1 | grep -q -- '-e filename' && eflag=(-e "$ng/error.log")
"$nginx_bin" -t -p "$ng/" -c "$ng/nginx.conf" "${eflag[@]}" 2>"$ng/test.log" || { cat "$ng/test.log" >&2; exit 1; }
"$nginx_bin" -p "$ng/" -c "$ng/nginx.conf" "${eflag[@]}" &
nginx_pid=$!
base="http://127.0.0.1:$nport"
for _ in $(seq 100); do
  curl -s -o /dev/null "$base/healthz" && break
  kill -0 "$nginx_pid" 2>/dev/null || { cat "$ng/error.log" >&2; echo "nginx did not start" >&2; exit 1; }
  sleep 0.1
done
log "nginx: pid $nginx_pid at $base"

# ---- checks ------------------------------------------------------------
export MVKP="$mvkp" OUT="$out" DB="$db" BASE="$base" SECS="$secs" THREADS="$threads" CLIENTS="$clients" \
  INFLIGHT="$inflight" PY="$py" KEEPALIVE="$keepalive" MAX_FAILS="$max_fails" LOADAVG0="$loadavg0" \
  BODY_MB="$body_mb"
export P1="${rport[1]}" P2="${rport[2]}" PID1="${rpid[1]}" PID2="${rpid[2]}"

"$py" - phase1 <<'EOF'
import json, os, sys, urllib.error, urllib.request
base, out = os.environ["BASE"], os.environ["OUT"]
def get(url):
    with urllib.request.urlopen(url, timeout=30) as r:
        return r.status, r.headers.get("Content-Type", ""), r.read()
def recognized(p):
    with urllib.request.urlopen(f"http://127.0.0.1:{p}/metrics", timeout=30) as r:
        t = r.read().decode()
    return sum(int(l.split()[-1]) for l in t.splitlines() if l.startswith('mvkp_requests_total{route="/api/recognize",status="200"}'))
res = {}
s, ct, b = get(base + "/")
res["index_html"] = s == 200 and ct.startswith("text/html") and b"/app.js" in b
s, ct, b = get(base + "/healthz")
res["healthz"] = s == 200 and json.loads(b).get("exhibits") == 6
frames = sorted(os.listdir(out + "/frames"))
before = [recognized(os.environ["P1"]), recognized(os.environ["P2"])]
found = 0
for f in frames[:12]:
    req = urllib.request.Request(base + "/api/recognize", data=open(out + "/frames/" + f, "rb").read(),
                                 headers={"Content-Type": "image/png"})
    with urllib.request.urlopen(req, timeout=60) as r:
        found += bool(json.loads(r.read())["found"])
after = [recognized(os.environ["P1"]), recognized(os.environ["P2"])]
res["sequential_12"] = {"replica1": after[0] - before[0], "replica2": after[1] - before[1], "frames_with_exhibit": found}
res["spread"] = all(after[i] - before[i] > 0 for i in range(2))
def post(body):
    req = urllib.request.Request(base + "/api/recognize", data=body, headers={"Content-Type": "image/png"})
    try:
        with urllib.request.urlopen(req, timeout=120) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()
big = open(out + "/big/view_0000.png", "rb").read()
s_big, b_big = post(big)
s_over, _ = post(b"\0" * ((int(os.environ["BODY_MB"]) << 20) + 1))
res["big_frame"] = {"bytes": len(big), "status": s_big,
                    "found": [f["id"] for f in json.loads(b_big)["found"]] if s_big == 200 else None}
res["over_limit_status"] = s_over
res["bodies"] = s_big == 200 and s_over == 413
json.dump(res, open(out + "/checks1.json", "w"))
print("replicas: / %s, /healthz %s, 12 recognitions through nginx: %d on replica 1, %d on replica 2"
      % ("ok" if res["index_html"] else "FAIL", "ok" if res["healthz"] else "FAIL",
         res["sequential_12"]["replica1"], res["sequential_12"]["replica2"]))
print("replicas: a %.1f MB frame through nginx: %s %s; %s MiB + 1 byte: %s -> %s"
      % (len(big) / 1e6, s_big, res["big_frame"]["found"], os.environ["BODY_MB"], s_over,
         "ok" if res["bodies"] else "FAIL"))
EOF

# ---- load ----------------------------------------------------------------
# scripts/loadtest.py starts a server of its own and reads its port from the
# first stderr line. This stand-in for `mvkp serve` prints the port of the
# server or nginx under test ($SHIM_PORT) and waits for loadtest.py's
# SIGTERM, so every run below uses the same load generator against servers
# this script started and can measure (loadtest.py's RSS fields are the
# stand-in's and are left out).
cat >"$out/shim.sh" <<'EOF'
#!/bin/sh
echo "{\"event\":\"listening\",\"port\":$SHIM_PORT,\"via\":\"scripts/replicas.sh\"}" >&2
exec sleep infinity
EOF
chmod +x "$out/shim.sh"

# ticks PID...: CPU time (user + system, clock ticks) of the processes
ticks() { local p t=0; for p in "$@"; do t=$((t + $(awk '{print $14 + $15}' "/proc/$p/stat"))); done; echo "$t"; }
# recognized PORT: recognitions answered 200 so far
recognized() { curl -s "http://127.0.0.1:$1/metrics" | awk '/^mvkp_requests_total\{route="\/api\/recognize",status="200"\}/ {n = $2} END {print n + 0}'; }
rss_kb() { awk '/VmRSS/ {print $2}' "/proc/$1/status"; }

# run_load NAME PORT "SERVER_PIDS" "SERVER_PORTS": loadtest.py against PORT;
# adds the servers' CPU seconds and recognitions over the whole run (warm-up
# included) to OUT/load-NAME.json.
# shellcheck disable=SC2086  # the pid lists are split on purpose
run_load() {
  local name=$1 port=$2 spids=$3 sports=$4 t0 t1 n0="" n1="" p w0 w1 ngx_pids ng0 ng1 rss=""
  ngx_pids=$(pgrep -P "$nginx_pid" | tr '\n' ' ')
  t0=$(ticks $spids); ng0=$(ticks $ngx_pids)
  for p in $sports; do n0="$n0 $(recognized "$p")"; done
  w0=$(date +%s.%N)
  SHIM_PORT=$port "$py" "$here/loadtest.py" --mvkp "$out/shim.sh" --db "$db" --frames "$out/frames" \
    --clients "$clients" --seconds "$secs" --warmup 3 --json "$out/load-$name.json" >"$out/load-$name.out" &
  lt_pid=$!
  wait "$lt_pid"
  lt_pid=""
  w1=$(date +%s.%N)
  t1=$(ticks $spids); ng1=$(ticks $ngx_pids)
  for p in $sports; do n1="$n1 $(recognized "$p")"; done
  for p in $spids; do rss="$rss $(rss_kb "$p")"; done
  "$py" - "$out/load-$name.json" "$t0" "$t1" "$ng0" "$ng1" "$w0" "$w1" "$n0" "$n1" "$rss" "$(getconf CLK_TCK)" <<'EOF'
import json, sys
f, t0, t1, ng0, ng1, w0, w1, n0, n1, rss, hz = sys.argv[1:]
d = json.load(open(f))
for k in [k for k in d if k.startswith("rss")]:
    del d[k]
hz = float(hz)
n = [int(b) - int(a) for a, b in zip(n0.split(), n1.split())]
cpu = (int(t1) - int(t0)) / hz
d.update({"server_cpu_s": round(cpu, 1), "wall_s": round(float(w1) - float(w0), 1),
          "recognized_per_server": n, "recognitions_per_cpu_s": round(sum(n) / cpu, 1) if cpu else None,
          "server_rss_mb": [round(int(x) / 1024, 1) for x in rss.split()],
          "nginx_cpu_s": round((int(ng1) - int(ng0)) / hz, 1)})
json.dump(d, open(f, "w"), indent=1)
EOF
}

log "load through nginx: $clients clients, ${secs} s, 2 replicas x $threads thread(s)"
run_load nginx "$nport" "${rpid[1]} ${rpid[2]}" "${rport[1]} ${rport[2]}"
log "load on replica 1 directly: $clients clients, ${secs} s, $threads thread(s)"
run_load "one-t$threads" "${rport[1]}" "${rpid[1]}" "${rport[1]}"
# One server with the pair's threads: the same CPU without nginx.
t2=$((2 * threads))
: >"$out/replica3.log"
threads=$t2 start_replica 3 0
log "load on a third server (pid ${rpid[3]}) directly: $clients clients, ${secs} s, $t2 thread(s)"
run_load "one-t$t2" "${rport[3]}" "${rpid[3]}" "${rport[3]}"
kill "${rpid[3]}"
wait "${rpid[3]}" || true
unset 'rpid[3]'

# d) failover: 4 clients through nginx; replica 1 gets SIGKILL after 2 s.
disown "${rpid[1]}"  # no "Killed" line from bash; it still reaps it
log "failover: 4 clients through nginx for 6 s, SIGKILL to replica 1 (pid ${rpid[1]}) after 2 s"
"$py" - failover <<'EOF'
import http.client, json, os, signal, threading, time
out, port = os.environ["OUT"], int(os.environ["BASE"].rsplit(":", 1)[1])
frames = [open(out + "/frames/" + f, "rb").read() for f in sorted(os.listdir(out + "/frames"))]
lock, st, phase = threading.Lock(), {"before": {}, "after": {}}, {"killed": False, "stop": False}
def client(k):
    i = k
    while not phase["stop"]:
        key = "after" if phase["killed"] else "before"
        try:
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
            c.request("POST", "/api/recognize", frames[i % len(frames)], {"Content-Type": "image/png"})
            code = c.getresponse().status
            c.close()
        except Exception as e:
            code = type(e).__name__
        i += 4
        with lock:
            st[key][str(code)] = st[key].get(str(code), 0) + 1
ts = [threading.Thread(target=client, args=(k,)) for k in range(4)]
for t in ts: t.start()
time.sleep(2)
os.kill(int(os.environ["PID1"]), signal.SIGKILL)
phase["killed"] = True
time.sleep(4)
phase["stop"] = True
for t in ts: t.join()
ok = all(k == "200" for d in st.values() for k in d) and st["after"].get("200", 0) > 0
json.dump({"status_before_kill": st["before"], "status_after_kill": st["after"], "all_200": ok},
          open(out + "/failover.json", "w"))
print("replicas: before the kill %s, after %s -> %s" % (st["before"], st["after"], "all 200" if ok else "FAIL"))
EOF
retried=$(grep -c 'while reading response header from upstream\|connect() failed' "$ng/error.log" || true)
log "nginx error.log: $retried upstream errors logged (each one sent on to replica 2)"

# The killed replica comes back on its port and gets requests again (with
# MAX_FAILS > 0 once fail_timeout is over).
start_replica 1 "${rport[1]}"
log "replica 1 restarted: pid ${rpid[1]} port ${rport[1]}"
[ "$max_fails" -gt 0 ] && sleep $((fail_timeout + 1))
export PID1="${rpid[1]}"
"$py" - rejoin <<'EOF'
import json, os, urllib.error, urllib.request
base, out = os.environ["BASE"], os.environ["OUT"]
def recognized(p):
    with urllib.request.urlopen(f"http://127.0.0.1:{p}/metrics", timeout=30) as r:
        t = r.read().decode()
    return sum(int(l.split()[-1]) for l in t.splitlines() if l.startswith('mvkp_requests_total{route="/api/recognize",status="200"}'))
frames = sorted(os.listdir(out + "/frames"))
codes = {}
for f in frames[:10]:
    req = urllib.request.Request(base + "/api/recognize", data=open(out + "/frames/" + f, "rb").read(),
                                 headers={"Content-Type": "image/png"})
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            codes[str(r.status)] = codes.get(str(r.status), 0) + 1
    except urllib.error.HTTPError as e:
        codes[str(e.code)] = codes.get(str(e.code), 0) + 1
n1 = recognized(os.environ["P1"])
res = {"status": codes, "replica1_after_restart": n1, "ok": codes == {"200": 10} and n1 > 0}
json.dump(res, open(out + "/rejoin.json", "w"))
print("replicas: 10 recognitions after the restart: %s, %d on the restarted replica 1 -> %s"
      % (codes, n1, "ok" if res["ok"] else "FAIL"))
EOF

# ---- summary -----------------------------------------------------------
"$py" - summary <<'EOF'
import json, os
e, out = os.environ, os.environ["OUT"]
T = int(e["THREADS"])
cores = os.cpu_count()
keys = ("requests", "ok", "status", "throughput_rps", "p50_ms", "p99_ms", "seconds", "server_cpu_s", "wall_s",
        "recognized_per_server", "recognitions_per_cpu_s", "server_rss_mb", "nginx_cpu_s")
def load(n):
    d = json.load(open(out + "/load-%s.json" % n))
    d = {k: d[k] for k in keys}
    d["server_cpu_share_of_machine"] = round(d["server_cpu_s"] / (d["wall_s"] * cores), 2)
    return d
c1 = json.load(open(out + "/checks1.json"))
fo = json.load(open(out + "/failover.json"))
rj = json.load(open(out + "/rejoin.json"))
runs = {"nginx -> 2 replicas x %d thr" % T: load("nginx"), "1 replica x %d thr" % T: load("one-t%d" % T),
        "1 server x %d thr" % (2 * T): load("one-t%d" % (2 * T))}
nginx, one, one2 = runs.values()
checks = {
    "index_html_via_nginx": c1["index_html"], "healthz_via_nginx": c1["healthz"],
    "spread_sequential": c1["spread"], "spread_under_load": min(nginx["recognized_per_server"]) > 0,
    "big_body_200_over_limit_413": c1["bodies"],
    "failover_all_200": fo["all_200"], "restarted_replica_rejoins": rj["ok"],
    "no_errors_in_load": all(set(x["status"]) <= {"200"} for x in runs.values()),
}
note = ("%d cores for everything: the replicas, nginx, the Python load generator and whatever else runs. Two "
        "replicas on one machine share its cores, so they cannot add throughput: compare nginx -> 2 x %d thread(s) "
        "with 1 server x %d threads (same CPU, no nginx); requests per CPU second is the rate per core, less "
        "sensitive to other load than req/s. Replicas on separate machines add their cores." % (cores, T, 2 * T))
summary = {
    "cores": cores, "loadavg_at_start": e["LOADAVG0"].split()[:3], "loadavg_at_end": open("/proc/loadavg").read().split()[:3],
    "clients": int(e["CLIENTS"]), "seconds": float(e["SECS"]), "replica_threads": T,
    "max_inflight_per_replica": int(e["INFLIGHT"]), "nginx_keepalive": int(e["KEEPALIVE"]),
    "nginx_max_fails": int(e["MAX_FAILS"]), "load": runs, "spread_sequential_12": c1["sequential_12"],
    "big_frame": c1["big_frame"], "over_limit_status": c1["over_limit_status"],
    "failover": fo, "rejoin": rj, "checks": checks, "note": note,
}
json.dump(summary, open(out + "/summary.json", "w"), indent=1)
print()
print("%-26s %6s %6s %6s %5s %6s %6s %7s %9s %s" % ("loadtest.py, %d clients, %gs" % (summary["clients"], summary["seconds"]),
      "req/s", "p50ms", "p99ms", "err", "cpu s", "share", "req/cpu", "RSS MB", "per server"))
for name, d in runs.items():
    err = sum(v for k, v in d["status"].items() if k != "200")
    print("%-26s %6.1f %6.0f %6.0f %5d %6.1f %6.2f %7.1f %9s %s" % (
        name, d["throughput_rps"], d["p50_ms"] or 0, d["p99_ms"] or 0, err, d["server_cpu_s"],
        d["server_cpu_share_of_machine"], d["recognitions_per_cpu_s"] or 0,
        "/".join("%.0f" % x for x in d["server_rss_mb"]), "/".join(map(str, d["recognized_per_server"]))))
print("(cpu s: the servers' CPU time over the run with warm-up; share: of %d cores x wall time; req/cpu: "
      "recognitions per CPU second = req/s per core; nginx itself: %.1f cpu s)" % (cores, nginx["nginx_cpu_s"]))
print("load average at start %s, at end %s" % (" ".join(summary["loadavg_at_start"]), " ".join(summary["loadavg_at_end"])))
print("note:", note)
print("checks:", ", ".join("%s %s" % (k, "ok" if v else "FAIL") for k, v in checks.items()))
print("summary:", out + "/summary.json")
EOF
"$py" -c 'import json,sys; c=json.load(open(sys.argv[1]))["checks"]; sys.exit(0 if all(c.values()) else 1)' "$out/summary.json"
