#!/usr/bin/env bash
# uninstall.sh MANIFEST: `make uninstall`. Removes every file `cmake --install`
# (`make install [PREFIX=...]`) listed in MANIFEST (<build>/install_manifest.txt),
# then the Python byte-code caches of the mvkp package and the directories of
# those files that are left empty, only where the path below the install
# prefix (the files' common directory) has a component named mvkp
# (include/mvkp/..., lib/cmake/mvkp, lib/python3/dist-packages/mvkp):
# directories shared with other software (bin, lib, include) are never removed.
set -u
manifest=${1:?usage: uninstall.sh BUILD/install_manifest.txt}
if [[ ! -f $manifest ]]; then
  echo "nothing installed from $(dirname "$manifest") (no $manifest)"
  exit 0
fi
mapfile -t files < <(grep -v '^$' "$manifest")
# The install prefix: the files' longest common directory.
root=$(dirname -- "${files[0]:-/}")
for f in "${files[@]}"; do
  while [[ $f != "$root"/* && $root != / ]]; do root=$(dirname -- "$root"); done
done
removed=0
missing=0
declare -A dirs=()
for f in "${files[@]}"; do
  if [[ -e $f || -L $f ]]; then
    rm -f -- "$f" && echo "removed $f" && removed=$((removed + 1))
  else
    missing=$((missing + 1))
  fi
  d=$(dirname -- "$f")
  while [[ $d == "$root"/* ]]; do
    rel=${d#"$root"}/
    [[ $rel == */mvkp/* ]] && dirs[$d]=1
    d=$(dirname -- "$d")
  done
done
# Deepest first: byte-code caches, then empty directories.
while IFS= read -r d; do
  [[ -d $d/__pycache__ ]] && rm -rf -- "$d/__pycache__" && echo "removed $d/__pycache__/"
  rmdir -- "$d" 2>/dev/null && echo "removed $d/"
done < <(printf '%s\n' "${!dirs[@]}" | awk '{ print gsub("/", "/"), $0 }' | sort -rn | cut -d' ' -f2-)
echo "uninstall: $removed files removed$( ((missing)) && echo ", $missing already gone")"
