#!/usr/bin/env bash
# clean-root-test.sh [PACKAGE_DIR] [ROOT]: the "clean install" check of issue 9
# on a real, fresh Debian 12 system: debootstrap a minimal bookworm (cached in
# ROOT.base; ROOT, default /tmp/mvkp-clean-root, is a fresh copy of it each
# run), install the .deb packages of PACKAGE_DIR (default build/packages, from
# `make deb`) with
# apt, which pulls their declared dependencies from the Debian mirror and
# nothing else, plus g++, cmake and pkg-config, then inside the chroot:
#   - build tests/consumer with find_package(mvkp) and run it;
#   - build the same program with `pkg-config --cflags --libs mvkp` and run it;
#   - run the installed CLI (train, synth, match);
#   - `import mvkp` in /usr/bin/python3 from / and train + match through it.
# So a missing Depends shows up as a failure here (CTest's deb_install uses
# this machine's libraries instead). Needs root, debootstrap and network;
# not part of CTest (minutes, and ~700 MB). MIRROR=... picks the mirror.
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PK=$(realpath "${1:-$HERE/build/packages}")
ROOT=${2:-/tmp/mvkp-clean-root}
MIRROR=${MIRROR:-http://deb.debian.org/debian}
[[ $(id -u) -eq 0 ]] || { echo "clean-root-test: needs root (debootstrap, chroot)"; exit 2; }
[[ $ROOT == /?*/?* ]] || { echo "clean-root-test: ROOT must be an absolute path at least two levels deep: $ROOT"; exit 2; }
command -v debootstrap >/dev/null || { echo "clean-root-test: apt-get install debootstrap"; exit 2; }
compgen -G "$PK/*.deb" >/dev/null || { echo "clean-root-test: no .deb in $PK (make deb)"; exit 2; }

# The debootstrapped base is cached in ROOT.base; every run starts from a fresh copy of it.
BASE=$ROOT.base
if [[ ! -x $BASE/usr/bin/apt-get ]]; then
  echo "== debootstrap bookworm (minbase) -> $BASE"
  rm -rf "$BASE"
  debootstrap --variant=minbase bookworm "$BASE" "$MIRROR" >"$BASE.log" 2>&1 || { tail -20 "$BASE.log"; exit 1; }
fi
for m in proc sys dev; do
  if mountpoint -q "$ROOT/$m" 2>/dev/null; then echo "clean-root-test: $ROOT/$m is mounted (another run?)"; exit 2; fi
done
rm -rf "$ROOT"
cp -a "$BASE" "$ROOT"
mounted=()
cleanup() { for m in "${mounted[@]}"; do umount "$m" 2>/dev/null || true; done; }
trap cleanup EXIT
for m in proc sys dev; do
  mountpoint -q "$ROOT/$m" || { mount --bind "/$m" "$ROOT/$m"; mounted+=("$ROOT/$m"); }
done
cp /etc/resolv.conf "$ROOT/etc/resolv.conf"
rm -rf "$ROOT/work"
mkdir -p "$ROOT/work/debs"
cp "$PK"/*.deb "$ROOT/work/debs/"
cp -r "$HERE/tests/consumer" "$ROOT/work/consumer"
cp "$HERE/samples/starry_night.jpg" "$ROOT/work/"

in_root() { chroot "$ROOT" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 \
  DEBIAN_FRONTEND=noninteractive "$@"; }
echo "== apt-get install the packages (their Depends from $MIRROR) + g++ cmake pkg-config"
in_root apt-get update -qq
before=$(in_root dpkg-query -W -f '${Package}\n' | wc -l)
in_root apt-get install -y -qq --no-install-recommends g++ cmake make pkg-config >/dev/null
# Only what the packages declare (no recommends): a missing Depends fails below.
in_root sh -c 'apt-get install -y -qq --no-install-recommends /work/debs/*.deb' >/dev/null
echo "   $(($(in_root dpkg-query -W -f '${Package}\n' | wc -l) - before)) packages installed into the fresh root;" \
  "mvkp packages: $(in_root dpkg-query -W -f '${Package} ${Version}, ' libmvkp-dev mvkp python3-mvkp 2>/dev/null)"

echo "== consumer: find_package(mvkp)"
in_root sh -ec 'cmake -S /work/consumer -B /work/cb -DCMAKE_BUILD_TYPE=Release >/work/cmake.log
  cmake --build /work/cb >/work/build.log
  grep "^mvkp_DIR" /work/cb/CMakeCache.txt
  cd /work && ./cb/consumer starry_night.jpg'
echo "== consumer: pkg-config --cflags --libs mvkp"
in_root sh -ec 'c++ -std=c++20 -O1 -o /work/pc_consumer /work/consumer/main.cc $(pkg-config --cflags --libs mvkp) \
    2>/work/pc.log || { cat /work/pc.log; exit 1; }  # OpenCV 4.6 headers warn under C++20
  pkg-config --cflags --libs mvkp
  cd /work && ./pc_consumer starry_night.jpg'
echo "== the CLI"
in_root sh -ec 'cd /work && mvkp train starry_night.jpg -o s.mvkp --quiet && mvkp synth starry_night.jpg --n 2 --seed 4 -o v >/dev/null
  mvkp match s.mvkp v/view_0000.png v/view_0001.png'
echo "== python3: import mvkp (from /)"
in_root sh -ec 'cd / && python3 -c "
import mvkp, numpy as np
print(\"mvkp\", mvkp.__version__, \"from\", mvkp.__file__)
t = mvkp.prepare_target(mvkp.load_image(\"/work/starry_night.jpg\"), 320)
m = mvkp.train(t, views=30)
view, H = mvkp.make_scene_view(t, 5)
r = mvkp.Matcher(m).match(view)
e = mvkp.mean_corner_error(r.homography, H, t.shape[1], t.shape[0])
assert r.found and e < 5, (r, e)
print(\"train + match:\", r, \"corner error %.2f px\" % e)
"
  python3 -m mvkp --help | head -3'
echo "clean-root-test: all passed in a fresh Debian 12 root ($ROOT)"
