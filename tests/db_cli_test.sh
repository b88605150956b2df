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
expect_ok "db export -o" "$MVKP" db export "$DB" -o "$T/export.json"
check "export holds every target" $PY -c "
import json, sys
j = json.load(open('$T/export.json'))
sys.exit(0 if len(j['targets']) == 4 and j['schema'] >= 1 else 1)"
expect_ok "db remove" "$MVKP" db remove "$DB" fruits
check "three left" test "$(count "$DB")" -eq 3
expect_fail "db remove an absent id" "no target 'fruits'" "$MVKP" db remove "$DB" fruits

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

cli_finish
