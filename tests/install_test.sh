#!/usr/bin/env bash
# Install test: `cmake --install` the build into a temporary prefix, check what was
# installed (CLI runs, public headers present, no tests or internal headers), then
# build tests/consumer -- a separate CMake project using find_package(mvkp) and
# mvkp::mvkp -- against that prefix and run it on a sample image.
#
# Run by CTest with SRC=<repo root>, BUILD=<build dir>, SAMPLES=<repo>/samples
# (optional: MVKP=<built mvkp binary> to check the build is complete first,
# CXX=<compiler> for the consumer). Needs no network.
# Output: one "ok: ..." / "FAIL: ..." line per check, then "N passed, M failed".
set -u

: "${SRC:?set SRC to the repository root}"
: "${BUILD:?set BUILD to the build directory}"
: "${SAMPLES:?set SAMPLES to the samples directory}"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/mvkp_install_test.XXXXXX") || exit 1
P=$TMP/prefix
# `cmake --install` rewrites $BUILD/install_manifest.txt, which `make uninstall`
# reads: keep the one from a real install, and leave none behind if there was none.
MANIFEST=$BUILD/install_manifest.txt
if [[ -f $MANIFEST ]]; then cp -p "$MANIFEST" "$TMP/manifest.saved"; fi
cleanup() {
  if [[ -f $TMP/manifest.saved ]]; then
    cp -p "$TMP/manifest.saved" "$MANIFEST"
  else
    rm -f "$MANIFEST"
  fi
  rm -rf "$TMP"
}
trap cleanup EXIT
# shellcheck source=check_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/check_lib.sh"

# --- 0. the build is complete ---------------------------------------------------

if [[ -n ${MVKP:-} ]]; then
  if [[ -x $MVKP ]]; then ok "built CLI exists: $MVKP"; else fail "CLI not built: $MVKP (build the project first)"; finish; fi
fi

# --- 1. install ---------------------------------------------------------------

if timeout 120 cmake --install "$BUILD" --prefix "$P" >"$TMP/install.log" 2>&1; then
  ok "cmake --install $BUILD --prefix <tmp>/prefix ($(grep -c '^-- ' "$TMP/install.log") files)"
else
  fail "cmake --install failed: $(tail_of "$TMP/install.log")"
  finish
fi

# --- 2. what was installed ----------------------------------------------------

if [[ -x $P/bin/mvkp ]]; then
  ok "bin/mvkp installed"
  if timeout 30 "$P/bin/mvkp" --help >"$TMP/help.out" 2>"$TMP/help.err" && [[ -s $TMP/help.out ]]; then
    ok "installed mvkp --help exits 0 ($(head -n 1 "$TMP/help.out"))"
  else
    fail "installed mvkp --help: exit/empty output: $(tail_of "$TMP/help.err" 3)"
  fi
else
  fail "bin/mvkp not installed"
fi

# Every public header of the source tree (not internal/, not tests) is installed, and nothing else.
expected=$(cd "$SRC/src" && find mvkp -name '*.h' -not -path '*/internal/*' -not -name '*_test*' | sort)
installed=$(cd "$P/include" 2>/dev/null && find mvkp -type f | sort)
if [[ -n $expected && $expected == "$installed" ]]; then
  ok "include/mvkp/ holds the $(wc -l <<<"$expected") public headers"
else
  fail "include/mvkp/ differs from the public headers: $(diff <(echo "$expected") <(echo "$installed") | grep '^[<>]' | tr '\n' ' ' | head -c 400)"
fi
for h in core/image_io.h train/trainer.h synth/synth.h match/matcher.h model/model.h index/knn_index.h; do
  [[ -f $P/include/mvkp/$h ]] || fail "include/mvkp/$h missing"
done
leaked=$(find "$P" \( -name '*_test*' -o -name internal -o -name '*.cc' \) -print)
if [[ -z $leaked ]]; then
  ok "no *_test*, *.cc or internal/ installed"
else
  fail "installed files that must not be: $(tr '\n' ' ' <<<"$leaked" | head -c 400)"
fi

config=$(find "$P" -path '*/cmake/mvkp/mvkpConfig.cmake' -print -quit)
if [[ -n $config && -f ${config%/*}/mvkpConfigVersion.cmake && -f ${config%/*}/mvkpTargets.cmake ]]; then
  ok "CMake package files installed: ${config#"$P"/}, mvkpConfigVersion.cmake, mvkpTargets.cmake"
else
  fail "CMake package files missing under $P (mvkpConfig.cmake: '${config:-none}')"
fi

# --- 3. a separate project builds against the installed package ---------------

CB=$TMP/consumer-build
compiler=()
[[ -n ${CXX:-} ]] && compiler=(-DCMAKE_CXX_COMPILER="$CXX")
if timeout 180 cmake -S "$SRC/tests/consumer" -B "$CB" -DCMAKE_PREFIX_PATH="$P" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF "${compiler[@]}" >"$TMP/configure.log" 2>&1; then
  ok "consumer configures with -DCMAKE_PREFIX_PATH=<tmp>/prefix"
else
  fail "consumer configure failed: $(grep -A3 -m1 'Error' "$TMP/configure.log" | tr '\n' ' ' | head -c 600)"
  finish
fi
mvkp_dir=$(sed -n 's/^mvkp_DIR:PATH=//p' "$CB/CMakeCache.txt")
if [[ $mvkp_dir == "$P"/* ]]; then
  ok "find_package(mvkp) used the installed package (${mvkp_dir#"$P"/})"
else
  fail "find_package(mvkp) found '$mvkp_dir', not the installed package under $P"
fi

if timeout 300 cmake --build "$CB" -j 2 >"$TMP/build.log" 2>&1 && [[ -x $CB/consumer ]]; then
  ok "consumer builds and links against mvkp::mvkp"
else
  fail "consumer build failed: $(grep -m3 -E 'error|undefined' "$TMP/build.log" | tr '\n' ' ' | head -c 600)"
  finish
fi

# --- 4. and works -----------------------------------------------------------------

timeout 300 "$CB/consumer" "$SAMPLES/starry_night.jpg" >"$TMP/run.out" 2>&1
rc=$?
sed 's/^/  consumer: /' "$TMP/run.out"
if ((rc == 0)); then
  ok "consumer on starry_night.jpg: $(tail -n 1 "$TMP/run.out")"
elif ((rc == 124)); then
  fail "consumer on starry_night.jpg: hang (killed by timeout 300)"
else
  fail "consumer on starry_night.jpg: exit $rc: $(tail -n 1 "$TMP/run.out")"
fi

finish
