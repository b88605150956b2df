#!/usr/bin/env bash
# Duplicate exhibits (issue 20): how often `mvkp db import` refuses an image
# that shows an exhibit already there, and how often it wrongly refuses a
# distinct one.
#   scripts/duplicate-eval.sh [MVKP] [OUTDIR] DISTINCT_IMAGE...
# 1. Imports every DISTINCT_IMAGE (ids d000, d001, ...) into a new database
#    with --keep-going: a distinct image refused as "looks like" another is a
#    false warning. Images training refuses (textureless) are counted apart.
# 2. For the first COPIES (default 20) imported ones, writes an exact copy and
#    a cropped (central 70-85 %), brightened (x1.25 + 15), shrunk (x0.7),
#    JPEG-80 copy, and imports them into the same database: each should be
#    refused as "looks like" its original.
# Writes OUTDIR/summary.json and prints it. Needs PYTHON (default /usr/bin/python3)
# with cv2 and numpy.
set -euo pipefail
mvkp=${1:?usage: duplicate-eval.sh MVKP OUTDIR IMAGE...}
out=${2:?usage: duplicate-eval.sh MVKP OUTDIR IMAGE...}
shift 2
copies=${COPIES:-20}
py=${PYTHON:-/usr/bin/python3}
rm -rf "$out"
mkdir -p "$out/distinct" "$out/copies"
i=0
printf 'id,image\n' >"$out/distinct/list.csv"
for img in "$@"; do
  id=$(printf 'd%03d' "$i")
  ext=${img##*.}
  cp "$img" "$out/distinct/$id.$ext"
  printf '%s,%s.%s\n' "$id" "$id" "$ext" >>"$out/distinct/list.csv"
  echo "$id $img" >>"$out/distinct/sources.txt"
  i=$((i + 1))
done
db=$out/dup.db
"$mvkp" db create "$db" >/dev/null
set +e
"$mvkp" db import "$db" "$out/distinct/list.csv" --keep-going >"$out/distinct.out" 2>"$out/distinct.err"
set -e
"$mvkp" db list "$db" --json >"$out/imported.json"
"$py" - "$out" "$copies" <<'PYEOF'
import csv, json, os, sys, cv2, numpy as np
out, copies = sys.argv[1], int(sys.argv[2])
ids = [t["id"] for t in json.load(open(os.path.join(out, "imported.json")))]
rows = ["id,image"]
for k, id in enumerate(sorted(ids)[:copies]):
    src = [f for f in os.listdir(os.path.join(out, "distinct")) if f.startswith(id + ".")][0]
    img = cv2.imread(os.path.join(out, "distinct", src))
    h, w = img.shape[:2]
    cv2.imwrite(os.path.join(out, "copies", f"{id}-exact.png"), img)
    rng = np.random.default_rng(k)
    a, b = rng.uniform(0.05, 0.15, 2)
    crop = img[int(b * h):int((0.85 + b / 2) * h), int(a * w):int((0.85 + a / 2) * w)]
    crop = np.clip(crop.astype(np.float32) * 1.25 + 15, 0, 255).astype(np.uint8)
    crop = cv2.resize(crop, None, fx=0.7, fy=0.7, interpolation=cv2.INTER_AREA)
    cv2.imwrite(os.path.join(out, "copies", f"{id}-crop.jpg"), crop, [cv2.IMWRITE_JPEG_QUALITY, 80])
    rows += [f"{id}-exact,{id}-exact.png", f"{id}-crop,{id}-crop.jpg"]
open(os.path.join(out, "copies", "list.csv"), "w").write("\n".join(rows) + "\n")
PYEOF
set +e
"$mvkp" db import "$db" "$out/copies/list.csv" --keep-going >"$out/copies.out" 2>"$out/copies.err"
set -e
"$py" - "$out" "$#" <<'PYEOF'
import json, os, re, sys
out, n = sys.argv[1], int(sys.argv[2])
def rows(path):
    r = {}
    for line in open(path):
        m = re.search(r"\(id '([^']+)'\): (.*)", line)
        if m: r[m.group(1)] = m.group(2)
    return r
d = rows(os.path.join(out, "distinct.err"))
c = rows(os.path.join(out, "copies.err"))
copies = [l.split(",")[0] for l in open(os.path.join(out, "copies", "list.csv")).read().split()[1:]]
false_warn = {k: v for k, v in d.items() if "looks like" in v}
untrainable = {k: v for k, v in d.items() if "looks like" not in v}
caught = [k for k in copies if k in c and re.search(r"looks like '%s'" % k.rsplit("-", 1)[0], c[k])]
s = {
    "distinct_images": n,
    "distinct_imported": n - len(d),
    "distinct_untrainable": len(untrainable),
    "distinct_false_warnings": len(false_warn),
    "false_warning_rows": false_warn,
    "copies": len(copies),
    "copies_refused_naming_original": len(caught),
    "exact_refused": sum(k.endswith("-exact") for k in caught),
    "crop_refused": sum(k.endswith("-crop") for k in caught),
    "copies_missed": [k for k in copies if k not in caught],
}
json.dump(s, open(os.path.join(out, "summary.json"), "w"), indent=1)
print(json.dumps(s, indent=1))
PYEOF
