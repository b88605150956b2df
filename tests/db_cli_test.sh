#!/usr/bin/env bash
# End-to-end tests of `mvkp db`: create, add, import (CSV and JSON, all or
# none), list, remove, export; a process killed during an add leaves the
# database intact; bad input fails cleanly and loses nothing.
#
# Run by CTest with MVKP=<mvkp binary> and SAMPLES=<repo>/samples.
set -u

# shellcheck source=cli_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/cli_lib.sh"
cli_init db

count() { "$MVKP" db list "$1" --json | $PY -c "import json,sys; print(len(json.load(sys.stdin)))"; }

DB=$T/museum.db
expect_ok "db create" "$MVKP" db create "$DB"
expect_fail "db create on an existing file" "$DB" "$MVKP" db create "$DB"
expect_ok "db add" "$MVKP" db add "$DB" --id starry --image "$SAMPLES/starry_night.jpg" --title "The Starry Night" \
  --artist "Vincent van Gogh" --year 1889 --url https://example.org/starry --meta '{"room": 3}'
check "one target" test "$(count "$DB")" -eq 1
expect_fail "db add: duplicate id" "already exists" "$MVKP" db add "$DB" --id starry --image "$SAMPLES/coffee.jpg"
expect_fail "db add: meta is not a JSON object" "meta" "$MVKP" db add "$DB" --id x --image "$SAMPLES/coffee.jpg" --meta '[1'
printf 'not an image' >"$T/bad.png"
expect_fail "db add: unreadable image" "$T/bad.png" "$MVKP" db add "$DB" --id bad --image "$T/bad.png"
check "failed adds stored nothing" test "$(count "$DB")" -eq 1

mkdir -p "$T/list"
cp "$SAMPLES/coffee.jpg" "$SAMPLES/fruits.jpg" "$SAMPLES/baboon.jpg" "$T/list/"
printf 'id,image,title,artist,year\ncoffee,coffee.jpg,"Coffee, black",,2010\nfruits,fruits.jpg,Fruits,,\n' >"$T/list/a.csv"
expect_ok "db import CSV" "$MVKP" db import "$DB" "$T/list/a.csv"
check "three targets" test "$(count "$DB")" -eq 3
printf 'id,image\nbaboon,baboon.jpg\ncoffee,coffee.jpg\n' >"$T/list/dup.csv"
expect_fail "db import with an id already stored" "already exists" "$MVKP" db import "$DB" "$T/list/dup.csv"
printf 'id,image\nbaboon,baboon.jpg\nghost,missing.jpg\n' >"$T/list/missing.csv"
expect_fail "db import with a missing image" "missing.jpg" "$MVKP" db import "$DB" "$T/list/missing.csv"
check "failed imports added nothing (all or none)" test "$(count "$DB")" -eq 3
printf '[{"id": "baboon", "image": "baboon.jpg", "title": "Baboon", "year": 1970, "meta": {"k": [1, 2]}}]' >"$T/list/b.json"
expect_ok "db import JSON" "$MVKP" db import "$DB" "$T/list/b.json"
expect_ok "db list --json" "$MVKP" db list "$DB" --json
check "list: 4 targets with their metadata" $PY -c "
import json, sys
j = json.load(open('$T/out'))
d = {t['id']: t for t in j}
ok = len(j) == 4 and d['starry']['title'] == 'The Starry Night' and d['starry']['meta'] == {'room': 3}
ok = ok and d['coffee']['title'] == 'Coffee, black' and d['baboon']['year'] == '1970' and d['baboon']['meta'] == {'k': [1, 2]}
ok = ok and d['starry']['width'] == 400 and d['starry']['added_at'].endswith('Z')
sys.exit(0 if ok else 1)"
expect_ok "db export without OUT: the metadata as JSON" "$MVKP" db export "$DB"
cp "$T/out" "$T/export.json"
check "metadata export holds every target" $PY -c "
import json, sys
j = json.load(open('$T/export.json'))
sys.exit(0 if len(j['targets']) == 4 and j['schema'] >= 1 else 1)"
expect_ok "db remove" "$MVKP" db remove "$DB" fruits
check "three left" test "$(count "$DB")" -eq 3
expect_fail "db remove an absent id" "no target 'fruits'" "$MVKP" db remove "$DB" fruits

# --- Backups that restore (issue 20) -------------------------------------------
same_rows() { # same_rows DB1 DB2: equal targets (all columns) and encodings
  $PY -c "
import sqlite3, sys
def rows(p):
    c = sqlite3.connect('file:' + p + '?mode=ro', uri=True)
    return (c.execute('SELECT * FROM targets ORDER BY id').fetchall(), c.execute('SELECT * FROM encodings ORDER BY id, kind').fetchall())
a, b = rows('$1'), rows('$2')
sys.exit(0 if a == b and len(a[0]) > 0 else 1)"
}
integrity_ok() { $PY -c "import sqlite3, sys; sys.exit(0 if sqlite3.connect('$1').execute('PRAGMA integrity_check').fetchall() == [('ok',)] else 1)"; }
expect_ok "db backup" "$MVKP" db backup "$DB" "$T/copy.db"
check "backup: every row and encoding equal" same_rows "$DB" "$T/copy.db"
check "backup: integrity_check ok" integrity_ok "$T/copy.db"
expect_fail "db backup refuses an existing OUT" "already exists" "$MVKP" db backup "$DB" "$T/copy.db"
expect_ok "db backup --force replaces it" "$MVKP" db backup "$DB" "$T/copy.db" --force
expect_fail "db backup onto the database itself" "database itself" "$MVKP" db backup "$DB" "$DB" --force
printf 'hello' >"$T/notdb.db"
expect_fail "db backup of a non-database" "not an mvkp target database" "$MVKP" db backup "$T/notdb.db" "$T/x.db"
check "no copy left by a failed backup" test ! -e "$T/x.db"

expect_ok "db export DB OUT.tar" "$MVKP" db export "$DB" "$T/museum.tar"
check "the archive lists with tar, manifest included" bash -c "tar tf '$T/museum.tar' | grep -qx mvkp-archive.json"
expect_fail "db export refuses an existing OUT" "already exists" "$MVKP" db export "$DB" "$T/museum.tar"
expect_ok "db import ARCHIVE into a new database" "$MVKP" db import "$T/restored.db" "$T/museum.tar"
check "restored: same ids, metadata, added_at, images, models, encodings" same_rows "$DB" "$T/restored.db"
check "restored: integrity_check ok" integrity_ok "$T/restored.db"
expect_ok "recognize a frame against the original" "$MVKP" recognize "$DB" "$SAMPLES/coffee.jpg" --json
cp "$T/out" "$T/rec_a.json"
expect_ok "recognize the frame against the restored database" "$MVKP" recognize "$T/restored.db" "$SAMPLES/coffee.jpg" --json
check "same recognitions (ids, outlines, inliers)" $PY -c "
import json, sys
def found(p):
    return [(f['id'], f['outline'], f['inliers']) for f in json.loads(open(p).read().strip().splitlines()[0])['found']]
a, b = found('$T/rec_a.json'), found('$T/out')
sys.exit(0 if a == b and a and a[0][0] == 'coffee' else 1)"
expect_fail "import the archive again: ids exist, named by entry" "entry 1" "$MVKP" db import "$T/restored.db" "$T/museum.tar"
check "nothing added by the failed re-import" test "$(count "$T/restored.db")" -eq "$(count "$DB")"
expect_fail "import a metadata-only JSON export" "metadata-only" "$MVKP" db import "$DB" "$T/export.json"
size=$(stat -c %s "$T/museum.tar")
head -c $((size / 2)) "$T/museum.tar" >"$T/truncated.tar"
expect_fail "import a truncated archive" "truncated" "$MVKP" db import "$T/new1.db" "$T/truncated.tar"
check "no database made by a truncated archive" test ! -e "$T/new1.db"
expect_fail "import a truncated archive into an existing database" "truncated" "$MVKP" db import "$T/copy.db" "$T/truncated.tar"
check "the existing database is untouched" same_rows "$DB" "$T/copy.db"
# One byte of a model changed: its entry is named; nothing is imported.
$PY -c "
d = bytearray(open('$T/museum.tar', 'rb').read())
i = d.index(b'targets/000002/model') + 512 + 100
d[i] ^= 0x55
open('$T/damaged.tar', 'wb').write(d)"
expect_fail "import an archive with a damaged model" "entry 2" "$MVKP" db import "$T/new2.db" "$T/damaged.tar"
check "no database made by a damaged archive" test ! -e "$T/new2.db"
run "$MVKP" db import "$T/new3.db" "$T/damaged.tar" --keep-going
check "archive --keep-going: exit 1, the damaged entry named, the others restored" $PY -c "
import sys
err = open('$T/err').read().splitlines()
sys.exit(0 if $RC == 1 and len(err) == 1 and 'entry 2' in err[0] and 'damaged' in err[0] else 1)"
check "archive --keep-going: two of three restored" test "$(count "$T/new3.db")" -eq 2
printf 'not a tar at all, just text' >"$T/junk.tar"
expect_fail "import a file that is not an archive" "not a usable target archive" "$MVKP" db import "$T/new4.db" "$T/junk.tar"

"$MVKP" db create "$T/empty.db" >/dev/null
expect_ok "export an empty database" "$MVKP" db export "$T/empty.db" "$T/empty.tar"
expect_ok "import it: an empty database" "$MVKP" db import "$T/empty2.db" "$T/empty.tar"
check "the empty restore exists and is empty" test "$(count "$T/empty2.db")" -eq 0
# A backup while another process adds a target: a whole checked copy, with or without it.
"$MVKP" db add "$DB" --id during --image "$SAMPLES/building.jpg" >/dev/null 2>&1 &
adder=$!
expect_ok "db backup while a db add runs" "$MVKP" db backup "$DB" "$T/during.db"
wait "$adder"
check "that backup passes integrity_check" integrity_ok "$T/during.db"
check "that backup has the earlier targets" $PY -c "
import sqlite3, sys
ids = {r[0] for r in sqlite3.connect('$T/during.db').execute('SELECT id FROM targets')}
sys.exit(0 if {'starry', 'coffee', 'baboon'} <= ids <= {'starry', 'coffee', 'baboon', 'during'} else 1)"
expect_ok "db remove the concurrent add" "$MVKP" db remove "$DB" during

# Imports name the failing row; --keep-going imports the rest (issue 20).
KG=$T/kg.db
expect_ok "db create (keep-going)" "$MVKP" db create "$KG"
$PY -c "open('$T/list/flat.pgm', 'wb').write(b'P5\n200 200\n255\n' + bytes([128]) * 40000)"
printf 'id,image,title\nkg-coffee,coffee.jpg,Coffee\nkg-flat,flat.pgm,Flat\nkg-fruits,fruits.jpg,Fruits\n' >"$T/list/flat.csv"
expect_fail "a textureless image stops the import and names its line" "flat.csv:3" "$MVKP" db import "$KG" "$T/list/flat.csv"
check "the failed import added nothing" test "$(count "$KG")" -eq 0
printf 'id,image,title\nkg-coffee,coffee.jpg,Coffee\nkg-flat,flat.pgm,Flat\nkg-ghost,missing.jpg,Ghost\nkg-fruits,fruits.jpg,Fruits\nkg-coffee,coffee.jpg,Again\n' >"$T/list/kg.csv"
expect_fail "without --keep-going: the first failing row, before any training" "kg.csv:4" "$MVKP" db import "$KG" "$T/list/kg.csv"
check "still nothing added" test "$(count "$KG")" -eq 0
run "$MVKP" db import "$KG" "$T/list/kg.csv" --keep-going
check "--keep-going: exit 1 when rows failed" test "$RC" -eq 1
check "--keep-going: every failing row named with its line and reason" $PY -c "
import sys
err = open('$T/err').read().splitlines()
want = [('kg.csv:3', 'texture'), ('kg.csv:4', 'missing.jpg'), ('kg.csv:6', 'twice')]
ok = len(err) == 3 and all(any(w in l and r in l for l in err) for w, r in want)
sys.exit(0 if ok else 1)"
check "--keep-going: the good rows are imported" test "$(count "$KG")" -eq 2
check "--keep-going: summary on stdout" grep -q "imported 2 of 5" "$T/out"
printf '[{"id": "kg-j1", "image": "baboon.jpg"}, {"id": "kg-j2", "image": "nope.jpg"}]' >"$T/list/kg.json"
run "$MVKP" db import "$KG" "$T/list/kg.json" --keep-going
check "JSON --keep-going: exit 1, the entry named" $PY -c "
import sys
err = open('$T/err').read().splitlines()
sys.exit(0 if $RC == 1 and len(err) == 1 and 'kg.json: entry 2' in err[0] and 'nope.jpg' in err[0] else 1)"
check "JSON --keep-going: the good entry imported" test "$(count "$KG")" -eq 3

# Duplicates (issue 20): an exact copy and a cropped, brightened, smaller copy
# of an exhibit are refused by name (two copies take each other's votes and
# neither is found); --allow-duplicate adds one; distinct images pass.
DUP=$T/dup.db
"$MVKP" db create "$DUP" >/dev/null
expect_ok "dup: first exhibit" "$MVKP" db add "$DUP" --id starry --image "$SAMPLES/starry_night.jpg"
expect_fail "dup: an exact copy is refused" "looks like 'starry'" \
  "$MVKP" db add "$DUP" --id starry-copy --image "$SAMPLES/starry_night.jpg"
$PY - "$SAMPLES/starry_night.jpg" "$T/starry_crop.jpg" <<'PYEOF'
import sys, cv2, numpy as np
img = cv2.imread(sys.argv[1])
h, w = img.shape[:2]
crop = img[int(0.1 * h):int(0.85 * h), int(0.05 * w):int(0.8 * w)]
crop = np.clip(crop.astype(np.float32) * 1.3 + 20, 0, 255).astype(np.uint8)
crop = cv2.resize(crop, None, fx=0.7, fy=0.7, interpolation=cv2.INTER_AREA)
cv2.imwrite(sys.argv[2], crop, [cv2.IMWRITE_JPEG_QUALITY, 80])
PYEOF
expect_fail "dup: a cropped, brighter, smaller copy is refused" "looks like 'starry'" \
  "$MVKP" db add "$DUP" --id starry-crop --image "$T/starry_crop.jpg"
check "dup: refused copies stored nothing" test "$(count "$DUP")" -eq 1
for s in coffee fruits baboon astronaut building; do
  expect_ok "dup: distinct $s is added" "$MVKP" db add "$DUP" --id "$s" --image "$SAMPLES/$s.jpg"
done
expect_ok "dup: --allow-duplicate adds a copy on purpose" \
  "$MVKP" db add "$DUP" --id starry-crop --image "$T/starry_crop.jpg" --allow-duplicate
mkdir -p "$T/duplist"
cp "$SAMPLES/coffee.jpg" "$T/duplist/coffee-again.jpg"
cp "$SAMPLES/baboon.jpg" "$T/duplist/b1.jpg"
cp "$SAMPLES/baboon.jpg" "$T/duplist/b2.jpg"
"$MVKP" db create "$T/dup2.db" >/dev/null
"$MVKP" db add "$T/dup2.db" --id coffee --image "$SAMPLES/coffee.jpg" >/dev/null
printf 'id,image\nb1,b1.jpg\nb2,b2.jpg\nc2,coffee-again.jpg\n' >"$T/duplist/l.csv"
expect_fail "dup: import names the row that repeats an earlier row" "l.csv:3 (id 'b2')" \
  "$MVKP" db import "$T/dup2.db" "$T/duplist/l.csv"
check "dup: all-or-none import added nothing" test "$(count "$T/dup2.db")" -eq 1
run "$MVKP" db import "$T/dup2.db" "$T/duplist/l.csv" --keep-going
check "dup: --keep-going imports the distinct row, exit 1" test "$RC" -eq 1 -a "$(count "$T/dup2.db")" -eq 2
check "dup: both duplicate rows are named" grep -q "l.csv:4 (id 'c2').*looks like 'coffee'" "$T/err"

# db set (issue 20): metadata changes, the model stays; bad values are refused.
expect_ok "db set" "$MVKP" db set "$DUP" coffee --title "Black coffee" --year 2011
check "db set: new title and year, other fields kept" $PY -c "
import json, subprocess, sys
j = {t['id']: t for t in json.loads(subprocess.check_output(['$MVKP', 'db', 'list', '$DUP', '--json']))}
sys.exit(0 if j['coffee']['title'] == 'Black coffee' and j['coffee']['year'] == '2011' else 1)"
expect_fail "db set: unknown id" "no target 'nope'" "$MVKP" db set "$DUP" nope --title x
expect_fail "db set: a bad link" "url" "$MVKP" db set "$DUP" coffee --url "javascript:alert(1)"
expect_fail "db set: nothing to change" "nothing to change" "$MVKP" db set "$DUP" coffee

# A process killed while adding leaves the database readable and consistent.
for delay in 0.05 0.15 0.3 0.5; do
  "$MVKP" db add "$DB" --id "killed$delay" --image "$SAMPLES/building.jpg" >/dev/null 2>&1 &
  pid=$!
  sleep "$delay"
  kill -9 "$pid" 2>/dev/null
  wait "$pid" 2>/dev/null
done
expect_ok "db list after killed adds" "$MVKP" db list "$DB" --json
check "killed adds: the earlier targets are intact, each killed add is all or nothing" $PY -c "
import json, sys
ids = {t['id'] for t in json.load(open('$T/out'))}
sys.exit(0 if {'starry', 'coffee', 'baboon'} <= ids and all(i in ('starry', 'coffee', 'baboon') or i.startswith('killed') for i in ids) else 1)"

# Bad databases.
expect_fail "db list: missing database" "$T/none.db" "$MVKP" db list "$T/none.db"
printf 'hello' >"$T/text.db"
expect_fail "db list: not a database" "not an mvkp target database" "$MVKP" db list "$T/text.db"
expect_fail "db add: missing database" "$T/none.db" "$MVKP" db add "$T/none.db" --id a --image "$SAMPLES/coffee.jpg"
check "no database created by a failed add" test ! -e "$T/none.db"

# Ids, links and metadata (issue 19): refused before training, with the reason.
expect_fail "db add: id '..'" "invalid target id" "$MVKP" db add "$DB" --id .. --image "$SAMPLES/coffee.jpg"
expect_fail "db add: javascript: link" "http" "$MVKP" db add "$DB" --id js --image "$SAMPLES/coffee.jpg" --url 'javascript:alert(1)'
expect_fail "db add: meta 100 levels deep" "nested deeper" "$MVKP" db add "$DB" --id deep --image "$SAMPLES/coffee.jpg" \
  --meta "$($PY -c "print('{\"a\":' * 100 + '1' + '}' * 100)")"
# A row stored deep before the limits: listing and export still work.
$PY -c "import sqlite3; c = sqlite3.connect('$DB'); c.execute('UPDATE targets SET meta = ? WHERE id = ?', ('{\"a\":' * 300000 + '1' + '}' * 300000, 'starry')); c.commit()"
expect_ok "db list --json with a 300 000-level meta row" "$MVKP" db list "$DB" --json
check "db list: that row's meta shows as {}" $PY -c "
import json, sys
j = json.loads(open('$T/out').read())
rows = j if isinstance(j, list) else j.get('targets', j)
sys.exit(0 if any(r['id'] == 'starry' and r['meta'] == {} for r in rows) else 1)"
expect_ok "db export with that row" "$MVKP" db export "$DB" "$T/deep.tar"
run "$MVKP" db import "$T/deep.db" "$T/deep.tar" --keep-going
check "its import names that row (meta too long), restores the others" $PY -c "
import sys
err = open('$T/err').read().splitlines()
sys.exit(0 if $RC == 1 and len(err) == 1 and \"id 'starry'\" in err[0] and 'meta' in err[0] else 1)"
check "the others restored" test "$(count "$T/deep.db")" -eq $(($(count "$DB") - 1))

cli_finish
