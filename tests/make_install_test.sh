#!/usr/bin/env bash
# `make install PREFIX=<tmp>` / `make uninstall` (issue 9): the install puts the
# library, headers, CMake package, pkg-config file, CLI and (when built) the
# Python module under PREFIX and nowhere else; the manifest lists exactly those
# files; the module imports from there; `make uninstall` removes every one of
# them, the module's byte-code caches and the mvkp directories, and leaves
# other files under PREFIX alone.
#
# Run by CTest with SRC=<repo root>, BUILD=<build dir> (built), PYTHON_MODULE=ON|OFF.
# Runs the Makefile's recipes with `make -o build` (the build is not redone).
# Output: "ok: ..." / "FAIL: ..." / "skip: ..." lines, then "N passed, M failed".
set -u

: "${SRC:?set SRC to the repository root}"
: "${BUILD:?set BUILD to the build directory}"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/mvkp_make_install.XXXXXX") || exit 1
P=$TMP/prefix
MANIFEST=$BUILD/install_manifest.txt
# Keep the manifest of a real install (make uninstall reads it), leave none if there was none.
[[ -f $MANIFEST ]] && cp -p "$MANIFEST" "$TMP/manifest.saved"
cleanup() {
  if [[ -f $TMP/manifest.saved ]]; then cp -p "$TMP/manifest.saved" "$MANIFEST"; else rm -f "$MANIFEST"; fi
  rm -rf "$TMP"
}
trap cleanup EXIT
# shellcheck source=check_lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/check_lib.sh"
python_wanted=0
[[ ${PYTHON_MODULE:-OFF} =~ ^(ON|On|on|1|TRUE|True|true|YES|yes)$ ]] && python_wanted=1

# Files of someone else under the same prefix: uninstall must leave them.
mkdir -p "$P/bin" "$P/lib/cmake/other" "$P/include"
echo keep >"$P/bin/other-tool"
echo keep >"$P/lib/cmake/other/otherConfig.cmake"

if timeout 300 make -C "$SRC" --no-print-directory -o build install BUILD="$BUILD" PREFIX="$P" >"$TMP/install.log" 2>&1; then
  ok "make install PREFIX=<tmp>/prefix ($(grep -c '^-- ' "$TMP/install.log") files)"
else
  fail "make install PREFIX=<tmp>/prefix: $(tail_of "$TMP/install.log")"
  finish
fi

missing=""
for f in bin/mvkp include/mvkp/match/matcher.h; do [[ -e $P/$f ]] || missing+="$f "; done
for pat in 'libmvkp_core.a' 'mvkpConfig.cmake' 'mvkp.pc'; do
  [[ -n $(find "$P" -name "$pat" -print -quit) ]] || missing+="$pat "
done
if ((python_wanted)); then
  [[ -f $P/lib/python3/dist-packages/mvkp/__init__.py ]] || missing+="lib/python3/dist-packages/mvkp/__init__.py "
fi
if [[ -z $missing ]]; then
  ok "installed: CLI, headers, static libraries, CMake package, pkg-config file$( ((python_wanted)) && echo ", Python module")"
else
  fail "not installed under PREFIX: $missing"
fi

# The manifest lists exactly what the install added under PREFIX.
if [[ -f $MANIFEST ]]; then
  outside=$(grep -v "^$P/" "$MANIFEST" | head -3 | tr '\n' ' ')
  added=$(find "$P" \( -type f -o -type l \) ! -name other-tool ! -name otherConfig.cmake | sort)
  if [[ -z $outside && $added == "$(sort "$MANIFEST")" ]]; then
    ok "install_manifest.txt lists the $(grep -c . "$MANIFEST") installed files, all under PREFIX"
  else
    fail "manifest and installed files differ: outside PREFIX: $outside; $(diff <(echo "$added") <(sort "$MANIFEST") | grep '^[<>]' | head -5 | tr '\n' ' ')"
  fi
else
  fail "no $MANIFEST after make install"
fi

# pkg-config from the prefix: the relocatable file points into PREFIX.
pc=$(find "$P" -name mvkp.pc -print -quit)
if [[ -n $pc ]] && inc=$(PKG_CONFIG_PATH=${pc%/*} pkg-config --variable=includedir mvkp) &&
  [[ $(realpath -m "$inc") == "$(realpath "$P")/include" ]]; then
  ok "pkg-config mvkp from PREFIX: includedir is PREFIX/include"
else
  fail "pkg-config mvkp from PREFIX: includedir '${inc:-?}' (want $P/include)"
fi

if ((python_wanted)); then
  # Byte-code written on purpose: uninstall must remove the caches too.
  if (cd "$TMP" && PYTHONPATH="$P/lib/python3/dist-packages" timeout 60 /usr/bin/python3 -c \
      "import mvkp, os; print(os.path.realpath(mvkp.__file__))") >"$TMP/py.out" 2>&1 &&
    [[ $(tail -n 1 "$TMP/py.out") == "$(realpath "$P")"/* ]]; then
    ok "import mvkp from PREFIX/lib/python3/dist-packages"
  else
    fail "import mvkp from PREFIX: $(tail_of "$TMP/py.out")"
  fi
else
  skip "Python module: the build has none (MVKP_BUILD_PYTHON=OFF)"
fi

if timeout 60 make -C "$SRC" --no-print-directory uninstall BUILD="$BUILD" >"$TMP/uninstall.log" 2>&1; then
  ok "make uninstall: $(tail -n 1 "$TMP/uninstall.log")"
else
  fail "make uninstall: $(tail_of "$TMP/uninstall.log")"
fi
left=$(cd "$P" && find . -mindepth 1 | sort | tr '\n' ' ')
# Directories the install created outside mvkp/ (lib/pkgconfig, lib/python3/dist-packages) may stay, empty.
extra=$(cd "$P" && find . -mindepth 1 \( -type f -o -type l -o -path '*mvkp*' \) | sort | grep -v -x -e ./bin/other-tool -e ./lib/cmake/other/otherConfig.cmake | tr '\n' ' ')
if [[ -z $extra && -f $P/bin/other-tool && -f $P/lib/cmake/other/otherConfig.cmake ]]; then
  ok "after uninstall only the other software's files remain (and empty shared directories: $(cd "$P" && find . -mindepth 1 -type d -empty | sort | tr '\n' ' '))"
else
  fail "after uninstall: left behind: ${extra:-none}; other files kept: $(ls "$P/bin" 2>/dev/null | tr '\n' ' ') (tree: $left)"
fi

finish
