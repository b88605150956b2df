#!/usr/bin/env bash
# End-to-end tests of `mvkp knn`: results of exact (FFVA), approx and brute force
# against a Python brute-force reference, --batch, --save-index and loading the
# saved index, --dump-descriptors, and clean failures (exit exactly 1, one stderr
# line, no crash, no hang) on every kind of bad input.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples. Needs no network;
# the Python side uses the standard library only. Output: one "ok: ..." /
# "FAIL: ..." line per check, then "N passed, M failed".
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init knn

# pycheck DESC ARGS... <<'EOF' script EOF: ok if the Python script exits 0; its last
# output line is shown either way.
pycheck() {
  local desc=$1; shift
  local msg
  if msg=$("$PY" - "$@" 2>&1); then
    ok "$desc${msg:+: $(tail -n 1 <<<"$msg")}"
  else
    fail "$desc: $(tail -n 1 <<<"$msg")"
  fi
}

# --- fixtures ----------------------------------------------------------------

# Integer-valued vectors, so that every squared distance is exact in float and
# ties (broken by the smaller id) are common.
"$PY" - "$T" <<'EOF' || { echo "FAIL: cannot create .fvecs fixtures with python3"; exit 1; }
import random, struct, sys
t = sys.argv[1]
def write(name, rows, dim=None):
    with open(f"{t}/{name}", "wb") as f:
        for r in rows:
            f.write(struct.pack("<i", len(r) if dim is None else dim))
            f.write(struct.pack(f"<{len(r)}f", *r))
rng = random.Random(11)
def ints(n, dim, hi):
    return [[rng.randint(0, hi) for _ in range(dim)] for _ in range(n)]
for dim, hi in ((8, 4), (37, 9)):
    db = ints(300, dim, hi)
    db[17] = list(db[5])            # exact duplicates: equal distances, id order decides
    db[250] = list(db[5])
    q = ints(40, dim, hi)
    q[0] = list(db[5])              # a query equal to three database rows
    write(f"db{dim}.fvecs", db)
    write(f"q{dim}.fvecs", q)
write("small5.fvecs", ints(5, 8, 4))
write("q64.fvecs", ints(3, 64, 4))
nan_db = ints(20, 8, 4); nan_db[7][3] = float("nan")
write("nan_db.fvecs", nan_db)
inf_q = ints(4, 8, 4); inf_q[2][0] = float("inf")
write("inf_q.fvecs", inf_q)
ok = open(f"{t}/db8.fvecs", "rb").read()
open(f"{t}/truncated.fvecs", "wb").write(ok[:-3])
open(f"{t}/negdim.fvecs", "wb").write(struct.pack("<i", -1) + ok[4:])
write("mixed.fvecs", [[1, 2, 3], [1, 2]])
open(f"{t}/empty.fvecs", "wb").close()
open(f"{t}/text.fvecs", "w").write("this is not an fvecs file\n")
EOF
# A flat grey image: no keypoints, so no descriptors.
{ printf 'P5 64 64 255\n'; head -c 4096 /dev/zero | tr '\0' '\200'; } >"$T/flat.pgm"
mkdir -p "$T/a_directory.fvecs"

# --- 1. --dump-descriptors ---------------------------------------------------

imgs=("$SAMPLES"/*.jpg)
expect_ok "dump-descriptors from ${#imgs[@]} sample images" "$MVKP" knn --dump-descriptors "${imgs[@]}" -o "$T/wh.fvecs"
cp "$T/out" "$T/dump_msg"
pycheck "dump-descriptors: valid 20-D fvecs, size = count*(4+80), count as printed" "$T/wh.fvecs" "$T/dump_msg" <<'EOF'
import os, re, struct, sys
path, msg = sys.argv[1], open(sys.argv[2]).read()
m = re.search(r"wrote (\d+) descriptors \(dim (\d+)\) from (\d+) images to (\S+)", msg)
assert m, f"unexpected message: {msg!r}"
count, dim = int(m[1]), int(m[2])
assert dim == 20 and m[4] == path, msg
size = os.path.getsize(path)
assert count > 100 and size == count * (4 + 4 * 20), f"{count} descriptors, {size} bytes"
data = open(path, "rb").read()
for i in range(count):
    assert struct.unpack_from("<i", data, i * 84)[0] == 20, f"record {i} dimension"
print(f"{count} descriptors, {size} bytes")
EOF
expect_ok "dump-descriptors --max-per-image 7 on 2 images" \
  "$MVKP" knn --dump-descriptors "$SAMPLES/coffee.jpg" "$SAMPLES/baboon.jpg" -o "$T/wh14.fvecs" --max-per-image 7
check "--max-per-image 7: 14 records of 84 bytes" test "$(stat -c %s "$T/wh14.fvecs" 2>/dev/null)" = $((14 * 84))
expect_ok "dump-descriptors: an image without descriptors next to a good one" \
  "$MVKP" knn --dump-descriptors "$T/flat.pgm" "$SAMPLES/coffee.jpg" -o "$T/wh_flat.fvecs"
check "dump-descriptors: says the flat image gave no descriptors" grep -qF "$T/flat.pgm: no descriptors" "$T/err"
check "dump-descriptors: stdout counts the image without descriptors" grep -qF "(1 with no descriptors)" "$T/out"
check "--max-per-image keeps each image's first descriptors" \
  "$PY" -c 'import sys; a=open(sys.argv[1],"rb").read(); b=open(sys.argv[2],"rb").read(); sys.exit(a[:7*84] != b[:7*84])' \
  "$T/wh14.fvecs" "$T/wh_flat.fvecs"
expect_fail "dump-descriptors: only images without descriptors" "no descriptors" \
  "$MVKP" knn --dump-descriptors "$T/flat.pgm" -o "$T/none.fvecs"
check "dump-descriptors: no file written when there are no descriptors" test ! -e "$T/none.fvecs"
expect_fail "dump-descriptors without -o" "-o" "$MVKP" knn --dump-descriptors "$SAMPLES/coffee.jpg"
expect_fail "dump-descriptors: missing image" "$T/no_such.png" \
  "$MVKP" knn --dump-descriptors "$T/no_such.png" -o "$T/x.fvecs"
expect_fail "dump-descriptors: .fvecs file as an image" "$T/db8.fvecs" \
  "$MVKP" knn --dump-descriptors "$T/db8.fvecs" -o "$T/x.fvecs"

# The descriptors themselves are a database: query it with itself.
expect_ok "knn on dumped WH descriptors, exact, k 3" "$MVKP" knn "$T/wh.fvecs" "$T/wh14.fvecs" --k 3 --json
pycheck "WH self-query: each query's nearest neighbour is at distance 0" "$T/out" <<'EOF'
import json, sys
o = json.load(open(sys.argv[1]))
assert o["dim"] == 20 and o["nq"] == 14, o
assert all(d[0] == 0 for d in o["distances"]), o["distances"]
EOF

# --- 2. exact / approx / brute against a Python reference --------------------

K=7
for dim in 8 37; do
  for mode in exact approx brute; do
    expect_ok "knn dim $dim --mode $mode --k $K --json" "$MVKP" knn "$T/db$dim.fvecs" "$T/q$dim.fvecs" --k $K --mode $mode --json
    cp "$T/out" "$T/$mode$dim.json"
    expect_ok "knn dim $dim --mode $mode --k $K --json --batch" \
      "$MVKP" knn "$T/db$dim.fvecs" "$T/q$dim.fvecs" --k $K --mode $mode --json --batch
    cp "$T/out" "$T/${mode}_batch$dim.json"
  done
  pycheck "dim $dim: exact, brute and the Python reference agree (ids and distances, ties by id)" \
    "$T/db$dim.fvecs" "$T/q$dim.fvecs" "$T/exact$dim.json" "$T/brute$dim.json" $K <<'EOF'
import json, struct, sys
def read(path):
    data, rows, off = open(path, "rb").read(), [], 0
    while off < len(data):
        d = struct.unpack_from("<i", data, off)[0]
        rows.append(struct.unpack_from(f"<{d}f", data, off + 4)); off += 4 + 4 * d
    return rows
db, qs, k = read(sys.argv[1]), read(sys.argv[2]), int(sys.argv[5])
ref_ids, ref_d = [], []
for q in qs:
    d = sorted((sum((a - b) ** 2 for a, b in zip(x, q)), i) for i, x in enumerate(db))[:k]
    ref_ids.append([i for _, i in d]); ref_d.append([float(v) for v, _ in d])
for name in sys.argv[3:5]:
    o = json.load(open(name))
    assert o["neighbors"] == ref_ids, f"{name}: ids differ from reference, first query {o['neighbors'][0]} vs {ref_ids[0]}"
    assert o["distances"] == ref_d, f"{name}: distances differ from reference"
assert ref_ids[0][:3] == [5, 17, 250] and ref_d[0][:3] == [0.0] * 3, ref_ids[0]
ties = sum(len(set(r)) < len(r) for r in ref_d)
print(f"{len(qs)} queries, {ties} with tied distances")
EOF
  pycheck "dim $dim: --json has every field, sane values" "$T/exact$dim.json" "$T/brute$dim.json" "$T/exact_batch$dim.json" \
    "$T/db$dim.fvecs" "$T/q$dim.fvecs" $dim $K <<'EOF'
import json, sys
single, brute, batch = (json.load(open(p)) for p in sys.argv[1:4])
db, q, dim, k = sys.argv[4], sys.argv[5], int(sys.argv[6]), int(sys.argv[7])
need = ["db", "queries", "n", "dim", "nq", "k", "mode", "metric", "build_ms", "search_ms", "us_per_query",
        "distance_computations_per_query", "bytes_per_vector", "raw_bytes_per_vector", "neighbors", "distances"]
for o in (single, brute, batch):
    miss = [f for f in need if f not in o]
    assert not miss, f"missing {miss}"
    assert (o["db"], o["queries"], o["n"], o["dim"], o["nq"], o["k"]) == (db, q, 300, dim, 40, k), o
    assert o["metric"] == "squared_l2" and o["raw_bytes_per_vector"] == 4 * dim, o
    assert o["bytes_per_vector"] > 0 and o["search_ms"] >= 0 and o["build_ms"] >= 0
assert "median_us_per_query" in single and "median_us_per_query" not in batch
assert single["mode"] == "exact" and brute["mode"] == "brute"
assert brute["distance_computations_per_query"] == 300, brute["distance_computations_per_query"]
assert 0 < single["distance_computations_per_query"] <= 300, single["distance_computations_per_query"]
print(f"exact: {single['distance_computations_per_query']:.1f} distances/query of 300")
EOF
  pycheck "dim $dim: approx returns $K valid neighbours per query, sorted, distances >= exact" \
    "$T/approx$dim.json" "$T/exact$dim.json" $K <<'EOF'
import json, sys
a, e, k = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), int(sys.argv[3])
assert a["mode"] == "approx" and len(a["neighbors"]) == 40
for ids, ds, eds in zip(a["neighbors"], a["distances"], e["distances"]):
    assert len(ids) == k and len(set(ids)) == k and all(0 <= i < 300 for i in ids), ids
    assert ds == sorted(ds) and all(x >= y for x, y in zip(ds, eds)), (ds, eds)
same = sum(x == y for x, y in zip(a["neighbors"], e["neighbors"]))
print(f"{same}/40 queries with exactly the exact neighbours")
EOF
  for mode in exact approx brute; do
    pycheck "dim $dim --mode $mode: --batch gives the same neighbours as single queries" \
      "$T/$mode$dim.json" "$T/${mode}_batch$dim.json" <<'EOF'
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
assert a["neighbors"] == b["neighbors"] and a["distances"] == b["distances"]
EOF
  done
done

# Human-readable output: one line per figure.
expect_ok "knn human output (exact)" "$MVKP" knn "$T/db8.fvecs" "$T/q8.fvecs" --k 3
for word in "300 vectors x 8 dims" "index build" "bytes/vector" "(raw 32)" "40 queries" "us  (median" "per query  ("; do
  check "human output has '$word'" grep -qF -- "$word" "$T/out"
done
expect_ok "knn human output (--batch)" "$MVKP" knn "$T/db8.fvecs" "$T/q8.fvecs" --k 3 --batch
check "batched human output has no median" test "$(grep -c median "$T/out")" = 0

# --- 3. --save-index and loading it back -------------------------------------

for mode in exact approx; do
  IDX=$T/$mode.idx
  expect_ok "--mode $mode --save-index" "$MVKP" knn "$T/db37.fvecs" "$T/q37.fvecs" --k $K --mode $mode --json --save-index "$IDX"
  cp "$T/out" "$T/built_$mode.json"
  check "$mode index file starts with MVKPFFVA" test "$(head -c 8 "$IDX" 2>/dev/null)" = MVKPFFVA
  expect_ok "load the saved $mode index as DB" "$MVKP" knn "$IDX" "$T/q37.fvecs" --k $K --json
  cp "$T/out" "$T/loaded_$mode.json"
  expect_ok "load the saved $mode index as DB, --no-verify --batch" "$MVKP" knn "$IDX" "$T/q37.fvecs" --k $K --json --no-verify --batch
  cp "$T/out" "$T/loaded_nv_$mode.json"
  pycheck "$mode: the loaded index gives the built index's results" \
    "$T/built_$mode.json" "$T/loaded_$mode.json" "$T/loaded_nv_$mode.json" "$mode" <<'EOF'
import json, sys
built, loaded, nv = (json.load(open(p)) for p in sys.argv[1:4])
for o in (loaded, nv):
    assert o["neighbors"] == built["neighbors"] and o["distances"] == built["distances"]
    assert o["mode"] == sys.argv[4] and "load_ms" in o and "build_ms" not in o, o.get("mode")
    assert (o["n"], o["dim"]) == (300, 37)
print(f"load {loaded['load_ms']:.3f} ms vs build {built['build_ms']:.3f} ms")
EOF
done
expect_ok "saved index: human output says it was loaded" "$MVKP" knn "$T/exact.idx" "$T/q37.fvecs" --k 2
check "human output has 'index load'" grep -qF "index load" "$T/out"

"$PY" - "$T/exact.idx" "$T" <<'EOF'
import sys
data = open(sys.argv[1], "rb").read()
t = sys.argv[2]
open(f"{t}/truncated.idx", "wb").write(data[: len(data) * 2 // 3])
open(f"{t}/header_only.idx", "wb").write(data[:100])
flipped = bytearray(data); flipped[len(data) // 2] ^= 0xFF          # in the sections: payload checksum
open(f"{t}/flipped.idx", "wb").write(flipped)
head = bytearray(data); head[40] ^= 0x01                             # in the header: header checksum
open(f"{t}/flipped_header.idx", "wb").write(head)
open(f"{t}/magic_only.idx", "wb").write(b"MVKPFFVA")
open(f"{t}/trailing.idx", "wb").write(data + b"\0" * 64)
EOF
expect_fail "truncated index file" "$T/truncated.idx" "$MVKP" knn "$T/truncated.idx" "$T/q37.fvecs" --k 3
expect_fail "index file cut inside its header" "$T/header_only.idx" "$MVKP" knn "$T/header_only.idx" "$T/q37.fvecs" --k 3
expect_fail "index file with a flipped byte" "checksum" "$MVKP" knn "$T/flipped.idx" "$T/q37.fvecs" --k 3
expect_fail "index file with a flipped header byte, --no-verify" "$T/flipped_header.idx" \
  "$MVKP" knn "$T/flipped_header.idx" "$T/q37.fvecs" --k 3 --no-verify
expect_fail "index file that is only the magic" "$T/magic_only.idx" "$MVKP" knn "$T/magic_only.idx" "$T/q37.fvecs" --k 3
expect_fail "index file with trailing bytes" "$T/trailing.idx" "$MVKP" knn "$T/trailing.idx" "$T/q37.fvecs" --k 3
# A payload flip with the checksum skipped may give wrong neighbours, but must not crash.
run "$MVKP" knn "$T/flipped.idx" "$T/q37.fvecs" --k 3 --no-verify
if why=$(process_problem); then fail "flipped index, --no-verify: $why"; else ok "flipped index, --no-verify: no crash (exit $RC)"; fi
expect_fail "saved index with queries of another dimension" "dimension mismatch" "$MVKP" knn "$T/exact.idx" "$T/q8.fvecs" --k 3
expect_fail "saved index with --k larger than it" "larger than the database" "$MVKP" knn "$T/exact.idx" "$T/q37.fvecs" --k 301
expect_fail "saved exact index with --mode approx" "--mode" "$MVKP" knn "$T/exact.idx" "$T/q37.fvecs" --k 3 --mode approx
expect_fail "--save-index with --mode brute" "--save-index needs --mode exact or approx" \
  "$MVKP" knn "$T/db8.fvecs" "$T/q8.fvecs" --k 3 --mode brute --save-index "$T/brute.idx"
check "--mode brute wrote no index" test ! -e "$T/brute.idx"
cp "$T/db8.fvecs" "$T/db8_copy.fvecs"
expect_fail "--save-index over the DB file" "overwrite" \
  "$MVKP" knn "$T/db8_copy.fvecs" "$T/q8.fvecs" --k 3 --save-index "$T/db8_copy.fvecs"
check "--save-index over the DB: DB left intact" cmp -s "$T/db8.fvecs" "$T/db8_copy.fvecs"
expect_fail "--save-index into a missing directory" "$T/no_dir/x.idx" \
  "$MVKP" knn "$T/db8.fvecs" "$T/q8.fvecs" --k 3 --save-index "$T/no_dir/x.idx"

# --- 4. bad input --------------------------------------------------------------

DB=$T/db8.fvecs
Q=$T/q8.fvecs
expect_fail "missing DB" "$T/no_such.fvecs" "$MVKP" knn "$T/no_such.fvecs" "$Q" --k 3
expect_fail "missing QUERIES" "$T/no_such.fvecs" "$MVKP" knn "$DB" "$T/no_such.fvecs" --k 3
expect_fail "directory as DB" "$T/a_directory.fvecs" "$MVKP" knn "$T/a_directory.fvecs" "$Q" --k 3
expect_fail "truncated DB" "truncated" "$MVKP" knn "$T/truncated.fvecs" "$Q" --k 3
expect_fail "truncated QUERIES" "truncated" "$MVKP" knn "$DB" "$T/truncated.fvecs" --k 3
expect_fail "DB with a negative dimension header" "$T/negdim.fvecs" "$MVKP" knn "$T/negdim.fvecs" "$Q" --k 3
expect_fail "DB with inconsistent dimensions" "inconsistent" "$MVKP" knn "$T/mixed.fvecs" "$Q" --k 1
expect_fail "text file as DB" "$T/text.fvecs" "$MVKP" knn "$T/text.fvecs" "$Q" --k 1
expect_fail "image as DB" "$SAMPLES/coffee.jpg" "$MVKP" knn "$SAMPLES/coffee.jpg" "$Q" --k 1
expect_fail "dimension mismatch" "dimension mismatch: DB has 8, queries have 64" "$MVKP" knn "$DB" "$T/q64.fvecs" --k 3
expect_fail "empty DB file" "$T/empty.fvecs" "$MVKP" knn "$T/empty.fvecs" "$Q" --k 3
expect_fail "empty QUERIES file" "$T/empty.fvecs" "$MVKP" knn "$DB" "$T/empty.fvecs" --k 3
expect_fail "--k 0" "--k" "$MVKP" knn "$DB" "$Q" --k 0
expect_fail "--k -2" "--k" "$MVKP" knn "$DB" "$Q" --k -2
expect_fail "--k 10 on a 5-vector DB" "--k 10 is larger than the database (5 vectors)" \
  "$MVKP" knn "$T/small5.fvecs" "$Q" --k 10
expect_ok "--k 5 on a 5-vector DB (k = n is fine)" "$MVKP" knn "$T/small5.fvecs" "$Q" --k 5
expect_fail "missing --k" "--k" "$MVKP" knn "$DB" "$Q"
for mode in exact approx brute; do
  expect_fail "NaN in DB (--mode $mode)" "$T/nan_db.fvecs" "$MVKP" knn "$T/nan_db.fvecs" "$Q" --k 3 --mode $mode
  expect_fail "inf in QUERIES (--mode $mode)" "$T/inf_q.fvecs" "$MVKP" knn "$DB" "$T/inf_q.fvecs" --k 3 --mode $mode
done
expect_fail "unknown --mode" "fast" "$MVKP" knn "$DB" "$Q" --k 3 --mode fast
expect_fail "neither DB/QUERIES nor --dump-descriptors" "nothing to do" "$MVKP" knn
expect_fail "DB without QUERIES" "QUERIES" "$MVKP" knn "$DB" --k 3
expect_fail "both DB and --dump-descriptors" "not both" \
  "$MVKP" knn "$DB" "$Q" --k 3 --dump-descriptors "$SAMPLES/coffee.jpg" -o "$T/both.fvecs"
check "both given: nothing written" test ! -e "$T/both.fvecs"
expect_fail "-o without --dump-descriptors" "--dump-descriptors" "$MVKP" knn "$DB" "$Q" --k 3 -o "$T/o.fvecs"

cli_finish
