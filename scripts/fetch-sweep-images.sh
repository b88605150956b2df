#!/usr/bin/env bash
# Target and background images for the envelope benchmark (`mvkp eval sweep`,
# issue 18), from Debian packages (downloaded with apt-get download and
# unpacked into a temporary folder; nothing is installed):
#   hold/         10 paintings never used while developing (Battle for Wesnoth
#                 story art, wesnoth-1.16-data, GPL-2+): the held-out targets
#   tune/         the targets we tuned on: samples/*.jpg and four other
#                 Wesnoth paintings of the same style
#   bg-hold/      real photos of streets, rooms, tables and plants (Ubuntu
#                 Touch wallpapers, lomiri-wallpapers-16.04, CC-BY-SA): the
#                 backgrounds of held-out runs
#   bg-tune/      OpenCV sample photos (opencv-doc, BSD) and scikit-image
#                 textures (python3-skimage): the backgrounds we tuned with
#   fetch-sweep-images.sh [DEST]        (default out/sweep-images)
# SWEEP_DEBS=DIR takes already downloaded .deb files from DIR. Backgrounds
# are downscaled to at most 1600 px (INTER_AREA); targets are kept as shipped.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
dest=${1:-out/sweep-images}
py=${PYTHON:-/usr/bin/python3}
die() { echo "fetch-sweep-images: $*" >&2; exit 1; }
"$py" -c 'import cv2' 2>/dev/null || die "needs $py with cv2 (apt-get install python3-opencv)"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/debs" "$tmp/root"
declare -A want=(
  [wesnoth-1.16-data]='./usr/share/games/wesnoth/1.16/data/core/images/story/*.jpg'
  [lomiri-wallpapers-16.04]='./usr/share/backgrounds/*.jpg'
  [opencv-doc]='./usr/share/doc/opencv-doc/examples/data/*'
  [python3-skimage]='./usr/lib/python3/dist-packages/skimage/data/*'
)
for p in "${!want[@]}"; do
  deb=""
  if [ -n "${SWEEP_DEBS:-}" ]; then
    shopt -s nullglob; c=("$SWEEP_DEBS/${p}"_*.deb); shopt -u nullglob
    [ ${#c[@]} -gt 0 ] && deb=${c[-1]}
  fi
  if [ -z "$deb" ]; then
    echo "fetch-sweep-images: apt-get download $p"
    (cd "$tmp/debs" && apt-get download "$p" >/dev/null 2>&1) || die "apt-get download $p failed (apt-get update first?)"
    shopt -s nullglob; c=("$tmp/debs/${p}"_*.deb); shopt -u nullglob
    deb=${c[0]}
  fi
  read -ra globs <<<"${want[$p]}"
  dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$tmp/root" --wildcards "${globs[@]}" || die "cannot unpack $deb"
done
W="$tmp/root/usr/share/games/wesnoth/1.16/data/core/images/story"
L="$tmp/root/usr/share/backgrounds"
OC="$tmp/root/usr/share/doc/opencv-doc/examples/data"
SK="$tmp/root/usr/lib/python3/dist-packages/skimage/data"
rm -rf "$dest"; mkdir -p "$dest"/{hold,tune,bg-hold,bg-tune}
for f in grim-altar landscape-battlefield landscape-bridge landscape-castle landscape-coast landscape-hills-01 \
         landscape-mountains-01 landscape-mountains-04 landscape-plain swamp-03; do
  cp "$W/$f.jpg" "$dest/hold/"
done
for f in landscape-hills-02 landscape-mountains-03 landscape-mountains-05 swamp-01; do cp "$W/$f.jpg" "$dest/tune/"; done
for f in starry_night building fruits baboon astronaut coffee; do cp "$here/samples/$f.jpg" "$dest/tune/"; done
"$py" - "$dest" "$L" "$OC" "$SK" <<'PY'
import sys, os, cv2
dest, L, OC, SK = sys.argv[1:]
def put(src, out):
    im = cv2.imread(src, cv2.IMREAD_COLOR)
    if im is None:
        sys.exit("fetch-sweep-images: cannot read " + src)
    s = 1600 / max(im.shape[:2])
    if s < 1:
        im = cv2.resize(im, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
    cv2.imwrite(out, im, [cv2.IMWRITE_JPEG_QUALITY, 92])
for f in ["Bridge_by_Sander_Klootwijk", "Dragonfly_by_Bolly", "Picture_0B_by_freespace", "Picture_1A_by_freespace",
          "Wine_by_Jakkub_Mede", "aitzgorri_by_Aitzol_Berasategi", "free_by_Peter_Nerlich", "friends_by_Aitzol_Berasategi",
          "life_by_Aitzol_Berasategi", "picosdeeuropa_by_Aitzol_Berasategi", "seeding_by_Clements_Engelhardt",
          "sunset_by_Aitzol_Berasategi"]:
    put(os.path.join(L, f + ".jpg"), os.path.join(dest, "bg-hold", f + ".jpg"))
for f in ["box_in_scene.png", "leuvenA.jpg", "leuvenB.jpg", "graf1.png", "aloeL.jpg", "stuff.jpg", "left01.jpg",
          "basketball1.png", "rubberwhale1.png", "smarties.png", "orange.jpg", "HappyFish.jpg"]:
    put(os.path.join(OC, f), os.path.join(dest, "bg-tune", "oc_" + os.path.splitext(f)[0] + ".jpg"))
for f in ["brick.png", "gravel.png", "grass.png", "rocket.jpg"]:
    put(os.path.join(SK, f), os.path.join(dest, "bg-tune", "sk_" + os.path.splitext(f)[0] + ".jpg"))
PY
for d in hold tune bg-hold bg-tune; do echo "$dest/$d: $(ls "$dest/$d" | wc -l) images"; done
