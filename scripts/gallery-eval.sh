#!/usr/bin/env bash
# Gallery recognition accuracy (issue 6): mvkp recognize against an OpenCV
# SIFT + RANSAC recogniser on synthetic gallery scenes and no-target frames.
#   scripts/gallery-eval.sh [MVKP] [OUTDIR]     (defaults: build/mvkp out/gallery)
# Environment:
#   SCENES=150 NOTARGET=300 SEED=1   sizes and seed of scripts/make-gallery.py
#   BATCH=50            frames per `mvkp recognize` call (argv limits)
#   GALLERY_DEBS=DIR    folder with opencv-doc_*.deb and python3-skimage_*.deb
#                       (else `apt-get download` into OUTDIR/debs)
#   QUALITY_IMAGES=DIR  output of scripts/fetch-quality-images.sh (default
#                       out/quality-images; fetched there when missing)
#   SIFT=0              skip the SIFT baseline
#   DB_ARGS=...         training options for `mvkp db import`
#                       (e.g. "--max-object-side 320 --min-scale 0.25")
#   RECOGNIZE_ARGS=...  extra options for `mvkp recognize`
#   PYTHON=/usr/bin/python3
# Steps: unpack the OpenCV and scikit-image sample data from their Debian
# packages; targets = paintings, photos and two posters of
# fetch-quality-images.sh (not poster_exhibition/poster_sale: they reuse the
# Great Wave and the cat photo), samples/*.jpg (not coffee.jpg, same as
# photo_coffee) and 7 OpenCV/scikit-image photos: 28 targets. Backgrounds and
# no-target frames: other photos of the same packages that show none of the
# targets (not box_in_scene.png, aero3.jpg, motorcycle_right.png, ...), plus
# frames of vtest.avi. Then make-gallery.py, `mvkp db create` + `db import`,
# `mvkp recognize --json` in batches, bench/sift_recognize.py on the same
# frames, and scripts/gallery_score.py -> OUTDIR/summary.{json,md}.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
mvkp=${1:-${MVKP:-build/mvkp}}
out=${2:-out/gallery}
py=${PYTHON:-/usr/bin/python3}
scenes=${SCENES:-150}
notarget=${NOTARGET:-300}
seed=${SEED:-1}
batch=${BATCH:-50}
qimg=${QUALITY_IMAGES:-out/quality-images}
die() { echo "gallery-eval: $*" >&2; exit 1; }
[ -x "$mvkp" ] || die "no mvkp binary at $mvkp (build first or pass it as the first argument)"
mvkp=$(cd "$(dirname "$mvkp")" && pwd)/$(basename "$mvkp")
"$py" -c 'import numpy, cv2; cv2.SIFT_create()' 2>/dev/null || die "needs $py with numpy and cv2 (with SIFT)"
export OMP_NUM_THREADS=1 OPENCV_FOR_THREADS_NUM=1
mkdir -p "$out"
out=$(cd "$out" && pwd)

# ---------------------------------------------------------------- images
if [ ! -f "$qimg/images.csv" ]; then
  echo "gallery-eval: fetching quality images into $qimg"
  QUALITY_IMAGES_DEBS=${GALLERY_DEBS:-${QUALITY_IMAGES_DEBS:-}} "$here/scripts/fetch-quality-images.sh" "$qimg"
fi
qimg=$(cd "$qimg" && pwd)
src="$out/debian"
OC="$src/usr/share/doc/opencv-doc/examples/data"
SK="$src/usr/lib/python3/dist-packages/skimage/data"
if [ ! -f "$OC/vtest.avi" ] || [ ! -f "$SK/retina.jpg" ]; then
  debs=${GALLERY_DEBS:-$out/debs}
  mkdir -p "$debs" "$src"
  for p in opencv-doc python3-skimage; do
    shopt -s nullglob; have=("$debs/${p}"_*.deb); shopt -u nullglob
    if [ ${#have[@]} -eq 0 ]; then
      echo "gallery-eval: apt-get download $p"
      (cd "$debs" && apt-get download "$p" >/dev/null) || die "apt-get download $p failed"
      shopt -s nullglob; have=("$debs/${p}"_*.deb); shopt -u nullglob
    fi
    case $p in
      opencv-doc) want='./usr/share/doc/opencv-doc/examples/data/*' ;;
      *) want='./usr/lib/python3/dist-packages/skimage/data/*' ;;
    esac
    dpkg-deb --fsys-tarfile "${have[-1]}" | tar -x -C "$src" --wildcards "$want" || die "cannot unpack ${have[-1]}"
  done
fi

list="$out/target-list.txt"
{
  for f in "$qimg"/painting_*.png "$qimg"/photo_*.png "$qimg/poster_cookie_box.png" "$qimg/poster_launch.png"; do
    echo "$f"
  done
  for f in astronaut baboon building fruits starry_night; do echo "$here/samples/$f.jpg"; done
  for f in aero1.jpg board.jpg butterfly.jpg home.jpg messi5.jpg; do echo "$OC/$f"; done
  for f in camera.png motorcycle_left.png; do echo "$SK/$f"; done
} >"$list"
while read -r f; do [ -f "$f" ] || die "target image missing: $f"; done <"$list"

bg="$out/backgrounds"
rm -rf "$bg"; mkdir -p "$bg"
for f in graf1.png graf3.png leuvenA.jpg leuvenB.jpg aloeL.jpg basketball1.png rubberwhale1.png smarties.png \
         stuff.jpg orange.jpg apple.jpg squirrel_cls.jpg chicky_512.png ela_original.jpg cards.png left01.jpg \
         left07.jpg licenseplate_motion.jpg Blender_Suzanne1.jpg HappyFish.jpg vtest.avi; do
  cp "$OC/$f" "$bg/oc_$f"
done
for f in retina.jpg coins.png moon.png ihc.png clock_motion.png grass.png gravel.png brick.png \
         text.png page.png hubble_deep_field.jpg cell.png; do
  cp "$SK/$f" "$bg/sk_$f"
done

# ---------------------------------------------------------------- frames
set_dir="$out/set"
t0=$(date +%s)
"$py" "$here/scripts/make-gallery.py" --targets "$list" --backgrounds "$bg" --out "$set_dir" \
  --scenes "$scenes" --no-target "$notarget" --seed "$seed" 2> >(grep -v '^libpng warning' >&2)
t1=$(date +%s)

# ---------------------------------------------------------------- mvkp
db="$out/gallery.db"
rm -f "$db" "$db-wal" "$db-shm"
"$mvkp" db create "$db" >/dev/null
# shellcheck disable=SC2086
"$mvkp" db import "$db" "$set_dir/targets.csv" ${DB_ARGS:-} 2> >(grep -v '^libpng warning' >&2)
t2=$(date +%s)
# shellcheck disable=SC2086
(cd "$set_dir" && xargs -a frames.txt -n "$batch" "$mvkp" recognize "$db" --json ${RECOGNIZE_ARGS:-}) \
  >"$out/mvkp.jsonl" || die "mvkp recognize failed (see $out/mvkp.jsonl)"
t3=$(date +%s)
runs=(--run "mvkp=$out/mvkp.jsonl")

# ---------------------------------------------------------------- SIFT
if [ "${SIFT:-1}" != 0 ]; then
  "$py" "$here/bench/sift_recognize.py" --targets "$set_dir/targets.csv" --frames "$set_dir/frames.txt" \
    --root "$set_dir" >"$out/sift.jsonl"
  runs+=(--run "sift=$out/sift.jsonl")
fi
t4=$(date +%s)

"$py" "$here/scripts/gallery_score.py" --gt "$set_dir/ground_truth.json" "${runs[@]}" \
  --json "$out/summary.json" --md "$out/summary.md" | tee "$out/score.txt"
echo "gallery-eval: frames $((t1 - t0)) s, db import $((t2 - t1)) s, mvkp recognize $((t3 - t2)) s," \
  "SIFT $((t4 - t3)) s; $out/summary.md, $out/summary.json"
