#!/usr/bin/env bash
# Package test (issue 9): build the .deb packages with CPack, check their
# control fields and contents, extract them with `dpkg-deb -x` into a fresh
# root (no root privileges, no dpkg database touched), and use them from there
# only:
#   - tests/consumer (a separate CMake project: find_package(mvkp), mvkp::mvkp)
#     configured with CMAKE_PREFIX_PATH=<root>/usr, built and run;
#   - the same program compiled with `pkg-config --cflags --libs mvkp`;
#   - the `mvkp` CLI from <root>/usr/bin: train, synth, match, and `mvkp serve`
#     answering /healthz and its linked-in web client;
#   - the Python module imported from <root>/usr/lib/python3/dist-packages with
#     the working directory outside the build tree, and called (skipped with a
#     "skip:" line when the build has no Python module, MVKP_BUILD_PYTHON=OFF).
# Every Depends entry must name a Debian package (checked with dpkg-query:
# the build machine has what the packages need).
#
# Run by CTest with SRC=<repo root>, BUILD=<build dir>, SAMPLES=<repo>/samples,
# MVKP=<built CLI>, CXX=<compiler>, PYTHON_MODULE=ON|OFF. Needs dpkg-dev and
# fakeroot (scripts/install-deps.sh). Output: "ok: ..." / "FAIL: ..." /
# "skip: ..." lines, then "N passed, M failed".
set -u

: "${SRC:?set SRC to the repository root}"
: "${BUILD:?set BUILD to the build directory}"
: "${SAMPLES:?set SAMPLES to the samples directory}"
CXX=${CXX:-c++}
PY=/usr/bin/python3
TMP=$(mktemp -d "${TMPDIR:-/tmp}/mvkp_deb_test.XXXXXX") || exit 1
SERVER_PID=
# cpack writes <build>/install_manifest_<component>.txt: remove those this test made.
made_manifests=()
for c in dev cli python; do [[ -e $BUILD/install_manifest_$c.txt ]] || made_manifests+=("$BUILD/install_manifest_$c.txt"); done
cleanup() {
  [[ -n $SERVER_PID ]] && kill "$SERVER_PID" 2>/dev/null
  rm -f "${made_manifests[@]}"
  rm -rf "$TMP"
}
trap cleanup EXIT
# shellcheck source=check_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/check_lib.sh"

for tool in cpack dpkg-deb dpkg-shlibdeps fakeroot pkg-config; do
  command -v "$tool" >/dev/null || { fail "$tool not found (scripts/install-deps.sh installs dpkg-dev, fakeroot)"; finish; }
done
if [[ -n ${MVKP:-} && ! -x $MVKP ]]; then fail "CLI not built: $MVKP (build the project first)"; finish; fi
python_wanted=0
[[ ${PYTHON_MODULE:-OFF} =~ ^(ON|On|on|1|TRUE|True|true|YES|yes)$ ]] && python_wanted=1

# --- 1. every install rule belongs to a packaged component ----------------------

components=$(grep -rhoE 'CMAKE_INSTALL_COMPONENT STREQUAL "[^"]+"' "$BUILD" --include=cmake_install.cmake |
  sed 's/.*"\(.*\)"/\1/' | sort -u | tr '\n' ' ')
packaged=$(sed -n 's/^set(CPACK_COMPONENTS_ALL "\(.*\)")$/\1/p' "$BUILD/CPackConfig.cmake" | tr ';' ' ')
stray=""
for c in $components; do [[ " $packaged " == *" $c "* ]] || stray+="$c "; done
if [[ -z $stray ]]; then
  ok "install components ($components) are all packaged ($packaged)"
else
  fail "install rules in components no package holds: $stray(packaged: $packaged)"
fi

# --- 2. build the packages --------------------------------------------------------

PK=$TMP/packages
t0=$SECONDS
if (cd "$BUILD" && timeout 900 cpack -G DEB --config "$BUILD/CPackConfig.cmake" -B "$PK") >"$TMP/cpack.log" 2>&1; then
  ok "cpack -G DEB ($((SECONDS - t0)) s)"
else
  fail "cpack failed: $(grep -iE 'error|warning' "$TMP/cpack.log" | head -5 | tr '\n' '|') $(tail_of "$TMP/cpack.log")"
  finish
fi
declare -A deb=()
for name in libmvkp-dev mvkp python3-mvkp; do
  f=$(find "$PK" -maxdepth 1 -name "${name}_*.deb" -print -quit)
  [[ -n $f ]] && deb[$name]=$f
done
expected=(libmvkp-dev mvkp)
((python_wanted)) && expected+=(python3-mvkp)
for name in "${expected[@]}"; do
  if [[ -n ${deb[$name]:-} ]]; then
    ok "package $(basename "${deb[$name]}") ($(du -k "${deb[$name]}" | cut -f1) KB)"
  else
    fail "package $name not built (have: $(cd "$PK" && ls *.deb 2>/dev/null | tr '\n' ' '))"
  fi
done
((python_wanted)) || skip "python3-mvkp: the build has no Python module (MVKP_BUILD_PYTHON=OFF)"

# --- 3. control fields: Depends present and naming real packages ---------------------

# depends_ok PKG FILE WANTED...: Depends is set, names installed packages, holds WANTED.
check_depends() {
  local name=$1 file=$2
  shift 2
  local dep
  dep=$(dpkg-deb -f "$file" Depends)
  echo "  $name Depends: $dep"
  if [[ -z $dep ]]; then
    fail "$name: no Depends field"
    return
  fi
  local unknown="" alt p any
  # "a (>= 1), b | c" -> one alternative group per line
  while IFS= read -r alt; do
    any=0
    for p in $(tr '|' '\n' <<<"$alt" | sed 's/(.*)//; s/ //g; s/:any$//'); do
      dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" && any=1
    done
    ((any)) || unknown+="$alt; "
  done < <(tr ',' '\n' <<<"$dep" | sed 's/^ *//')
  if [[ -z $unknown ]]; then
    ok "$name: every Depends entry is an installed Debian package"
  else
    fail "$name: Depends entries not installed here (wrong name?): $unknown"
  fi
  local w missing=""
  for w in "$@"; do grep -qE "(^|, |\| )$w( |,|$)" <<<"$dep" || missing+="$w "; done
  if [[ -z $missing ]]; then ok "$name: Depends names $*"; else fail "$name: Depends lacks $missing"; fi
}
[[ -n ${deb[libmvkp-dev]:-} ]] && check_depends libmvkp-dev "${deb[libmvkp-dev]}" \
  libopencv-dev libgdal-dev libsqlite3-dev nlohmann-json3-dev libjpeg-dev libpng-dev
[[ -n ${deb[mvkp]:-} ]] && check_depends mvkp "${deb[mvkp]}" \
  'libopencv-core[0-9.a-z-]*' 'libgdal[0-9]+' libsqlite3-0 'libjpeg62-turbo' 'libpng16-16' libstdc\\+\\+6 libc6
[[ -n ${deb[python3-mvkp]:-} ]] && check_depends python3-mvkp "${deb[python3-mvkp]}" \
  python3 python3-numpy 'libopencv-core[0-9.a-z-]*' libstdc\\+\\+6

# --- 4. contents ------------------------------------------------------------------------

contents() { dpkg-deb -c "$1" | awk '{ print $NF }' | sed 's|^\./|/|'; }
if [[ -n ${deb[libmvkp-dev]:-} ]]; then
  c=$(contents "${deb[libmvkp-dev]}")
  miss=""
  for want in '/usr/include/mvkp/match/matcher.h' '/usr/include/mvkp/cdikp/cdikp.h' '/usr/include/mvkp/index/ffva.h' \
      '/usr/lib/.*libmvkp_core\.a' '/usr/lib/.*cmake/mvkp/mvkpConfig\.cmake' '/usr/lib/.*cmake/mvkp/mvkpTargets\.cmake' \
      '/usr/lib/.*pkgconfig/mvkp\.pc'; do
    grep -qE "^$want$" <<<"$c" || miss+="$want "
  done
  leaked=$(grep -E '_test|/internal/|\.cc$|/bin/' <<<"$c" | head -3 | tr '\n' ' ')
  if [[ -z $miss && -z $leaked ]]; then
    ok "libmvkp-dev holds headers, $(grep -c '\.a$' <<<"$c") static libraries, CMake config, mvkp.pc (no tests, internal headers or programs)"
  else
    fail "libmvkp-dev contents: missing $miss; should not hold: $leaked"
  fi
fi
if [[ -n ${deb[mvkp]:-} ]]; then
  c=$(contents "${deb[mvkp]}")
  if grep -qx '/usr/bin/mvkp' <<<"$c" && ! grep -qE '\.(a|h)$' <<<"$c"; then
    ok "mvkp holds /usr/bin/mvkp (no libraries or headers)"
  else
    fail "mvkp contents: $(tr '\n' ' ' <<<"$c" | head -c 400)"
  fi
fi
if [[ -n ${deb[python3-mvkp]:-} ]]; then
  c=$(contents "${deb[python3-mvkp]}")
  if grep -qE '^/usr/lib/python3/dist-packages/mvkp/__init__\.py$' <<<"$c" &&
    grep -qE '^/usr/lib/python3/dist-packages/mvkp/.*\.so$' <<<"$c"; then
    ok "python3-mvkp holds /usr/lib/python3/dist-packages/mvkp ($(grep -c . <<<"$c") entries: $(grep -oE '[^/]+\.(so|pyi)$' <<<"$c" | head -4 | tr '\n' ' '))"
  else
    fail "python3-mvkp contents: $(tr '\n' ' ' <<<"$c" | head -c 600)"
  fi
fi

# --- 5. extract into a fresh root ------------------------------------------------------------

ROOT=$TMP/root
mkdir -p "$ROOT"
for f in "${deb[@]}"; do dpkg-deb -x "$f" "$ROOT" || fail "dpkg-deb -x $(basename "$f")"; done
ok "extracted ${#deb[@]} packages into <tmp>/root ($(find "$ROOT" -type f | wc -l) files)"
# No text file (CMake package, pkg-config, Python) points back at the build or
# source tree. (Binaries may: __FILE__ in assertion messages.)
refs=$(grep -rlIF -e "$BUILD" -e "$SRC/" "$ROOT" 2>/dev/null | sed "s|^$ROOT||" | head -5 | tr '\n' ' ')
if [[ -z $refs ]]; then ok "no installed text file names the build or source tree"; else fail "text files naming the build/source tree: $refs"; fi

# --- 6. the CMake consumer against <root>/usr ---------------------------------------------------

CB=$TMP/consumer-build
if timeout 180 cmake -S "$SRC/tests/consumer" -B "$CB" -DCMAKE_PREFIX_PATH="$ROOT/usr" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_CXX_COMPILER="$CXX" >"$TMP/configure.log" 2>&1; then
  mvkp_dir=$(sed -n 's/^mvkp_DIR:PATH=//p' "$CB/CMakeCache.txt")
  if [[ $mvkp_dir == "$ROOT"/* ]]; then
    ok "consumer: find_package(mvkp) found the package in the root (${mvkp_dir#"$ROOT"})"
  else
    fail "consumer: find_package(mvkp) found '$mvkp_dir', not the package under the root"
  fi
  if timeout 300 cmake --build "$CB" >"$TMP/build.log" 2>&1 && [[ -x $CB/consumer ]]; then
    ok "consumer builds and links against mvkp::mvkp from the package"
    if (cd "$TMP" && timeout 300 "$CB/consumer" "$SAMPLES/starry_night.jpg") >"$TMP/run.out" 2>&1; then
      ok "consumer runs: $(tail -n 1 "$TMP/run.out")"
    else
      fail "consumer run: $(tail_of "$TMP/run.out" 3)"
    fi
  else
    fail "consumer build: $(grep -m3 -E 'error|undefined' "$TMP/build.log" | tr '\n' ' ' | head -c 600)"
  fi
else
  fail "consumer configure: $(grep -A3 -m1 'Error' "$TMP/configure.log" | tr '\n' ' ' | head -c 600)"
fi

# --- 7. pkg-config --------------------------------------------------------------------------------

pc=$(find "$ROOT" -name mvkp.pc -print -quit)
if [[ -n $pc ]]; then
  export PKG_CONFIG_PATH=${pc%/*}
  if flags=$(pkg-config --cflags --libs mvkp 2>"$TMP/pc.err"); then
    ok "pkg-config --cflags --libs mvkp: $(head -c 160 <<<"$flags")..."
    # shellcheck disable=SC2086  # the flags are words
    if timeout 300 "$CXX" -std=c++20 -O1 -o "$TMP/pc_consumer" "$SRC/tests/consumer/main.cc" $flags >"$TMP/pc.log" 2>&1; then
      if (cd "$TMP" && timeout 300 "$TMP/pc_consumer" "$SAMPLES/starry_night.jpg") >"$TMP/pc.out" 2>&1; then
        ok "a program built with \$(pkg-config --cflags --libs mvkp) links and runs: $(tail -n 1 "$TMP/pc.out")"
      else
        fail "pkg-config program run: $(tail_of "$TMP/pc.out" 3)"
      fi
    else
      fail "c++ -std=c++20 main.cc \$(pkg-config --cflags --libs mvkp): $(grep -m3 -E 'error|undefined' "$TMP/pc.log" | tr '\n' ' ' | head -c 600)"
    fi
  else
    fail "pkg-config mvkp: $(tail_of "$TMP/pc.err")"
  fi
  unset PKG_CONFIG_PATH
else
  fail "no mvkp.pc in the packages"
fi

# --- 8. the CLI from the root -------------------------------------------------------------------

CLI=$ROOT/usr/bin/mvkp
if [[ -x $CLI ]]; then
  nf=$(ldd "$CLI" | grep 'not found' | tr '\n' ' ')
  [[ -z $nf ]] && ok "installed mvkp: every shared library resolves" || fail "installed mvkp: $nf"
  W=$TMP/cli
  mkdir -p "$W"
  if (cd "$W" && timeout 120 "$CLI" train "$SAMPLES/starry_night.jpg" -o starry.mvkp --quiet &&
      timeout 120 "$CLI" synth "$SAMPLES/starry_night.jpg" --n 2 --seed 4 -o views &&
      timeout 120 "$CLI" match starry.mvkp views/view_0000.png views/view_0001.png) >"$TMP/cli.out" 2>&1 &&
    [[ $(grep -c ': found' "$TMP/cli.out") -eq 2 ]]; then
    ok "installed mvkp train / synth / match: $(grep -m1 ': found' "$TMP/cli.out" | cut -c1-120)"
  else
    fail "installed mvkp train / synth / match: $(tail_of "$TMP/cli.out")"
  fi
  # mvkp serve: the museum guide with its linked-in web client.
  if (cd "$W" && "$CLI" db create museum.db && "$CLI" db add museum.db --id starry --image "$SAMPLES/starry_night.jpg" \
      --title "The Starry Night") >"$TMP/db.out" 2>&1; then
    (cd "$W" && exec "$CLI" serve museum.db --port 0 --threads 1) 2>"$TMP/serve.err" &
    SERVER_PID=$!
    port=
    for _ in $(seq 100); do
      port=$(sed -n 's/.*"event":"listening".*"port":\([0-9]*\).*/\1/p' "$TMP/serve.err" | head -1)
      [[ -n $port ]] && break
      sleep 0.1
    done
    if [[ -n $port ]] && "$PY" - "$port" "$SAMPLES/starry_night.jpg" >"$TMP/serve.out" 2>&1 <<'PYEOF'; then
import json, sys, urllib.request
base = f"http://127.0.0.1:{sys.argv[1]}"
assert urllib.request.urlopen(base + "/healthz", timeout=10).status == 200
page = urllib.request.urlopen(base + "/", timeout=10).read().decode()
assert "<html" in page.lower(), page[:200]
req = urllib.request.Request(base + "/api/recognize", data=open(sys.argv[2], "rb").read(),
                             headers={"Content-Type": "image/jpeg"})
found = json.load(urllib.request.urlopen(req, timeout=30))["found"]
assert found and found[0]["id"] == "starry", found
print("recognised", found[0]["title"])
PYEOF
      ok "installed mvkp serve: /healthz, the web client at /, $(tail -n 1 "$TMP/serve.out")"
    else
      fail "installed mvkp serve (port '${port}'): $(tail_of "$TMP/serve.out") $(tail_of "$TMP/serve.err" 3)"
    fi
    kill "$SERVER_PID" 2>/dev/null
    wait "$SERVER_PID" 2>/dev/null
    SERVER_PID=
  else
    fail "installed mvkp db create/add: $(tail_of "$TMP/db.out")"
  fi
  # mvkp video: the main binary execs the videoio helper from usr/libexec/mvkp.
  HELPER=$ROOT/usr/libexec/mvkp/mvkp-video
  if [[ -x $HELPER ]] && ! ldd "$HELPER" | grep -q 'not found' &&
    "$CLI" video --help >"$TMP/video.out" 2>&1 && grep -q 'SOURCE' "$TMP/video.out"; then
    ok "installed mvkp video: runs its helper usr/libexec/mvkp/mvkp-video"
  else
    fail "installed mvkp video (helper $HELPER): $(tail_of "$TMP/video.out")"
  fi
else
  fail "no usr/bin/mvkp in the root"
fi

# --- 9. the Python module from the root, outside the build tree -------------------------------

if ((python_wanted)) && [[ -n ${deb[python3-mvkp]:-} ]]; then
  SITE=$ROOT/usr/lib/python3/dist-packages
  while IFS= read -r so; do
    nf=$(ldd "$so" | grep 'not found' | tr '\n' ' ')
    [[ -z $nf ]] && ok "$(basename "$so"): every shared library resolves" || fail "$(basename "$so"): $nf"
  done < <(find "$SITE" -name '*.so')
  mkdir -p "$TMP/elsewhere"
  if (cd "$TMP/elsewhere" && env -u PYTHONHOME PYTHONPATH="$SITE" PYTHONDONTWRITEBYTECODE=1 PATH="$ROOT/usr/bin:$PATH" \
      timeout 300 "$PY" - "$SITE" "$SAMPLES/starry_night.jpg" "$BUILD" "$SRC") >"$TMP/py.out" 2>&1 <<'PYEOF'; then
import os, sys
site, image, build, src = sys.argv[1:5]
import numpy as np
import mvkp
where = os.path.realpath(mvkp.__file__)
assert where.startswith(os.path.realpath(site)), f"imported {where}, not the package"
for bad in (build, src):
    assert not any(os.path.realpath(p).startswith(os.path.realpath(bad)) for p in sys.path if p), f"{bad} on sys.path"
# Calls through the extension (no cv2 needed): train on a sample, find it in a generated view.
target = mvkp.prepare_target(mvkp.load_image(image), 320)
model = mvkp.train(target, views=30)
view, H = mvkp.make_scene_view(target, 5)
result = mvkp.Matcher(model).match(view)
assert result.found, result
error = mvkp.mean_corner_error(result.homography, H, target.shape[1], target.shape[0])
assert error < 5, error
print(f"import mvkp from {where.replace(site, '<root>/usr/lib/python3/dist-packages')}; "
      f"train + match: found, {result.inliers} inliers, corner error {error:.2f} px")
PYEOF
    ok "python3: $(tail -n 1 "$TMP/py.out")"
  else
    fail "python3 import from the root: $(tail_of "$TMP/py.out" 8)"
  fi
  if (cd "$TMP/elsewhere" && PYTHONPATH="$SITE" PATH="$ROOT/usr/bin:$PATH" timeout 60 "$PY" -m mvkp --help) >"$TMP/pym.out" 2>&1 &&
    grep -q 'train' "$TMP/pym.out"; then
    ok "python3 -m mvkp --help forwards to the CLI"
  else
    fail "python3 -m mvkp --help: $(tail_of "$TMP/pym.out" 4)"
  fi
elif ((python_wanted)); then
  fail "python3-mvkp missing: cannot test the import"
else
  skip "Python import from the root: the build has no Python module (MVKP_BUILD_PYTHON=OFF)"
fi

finish
