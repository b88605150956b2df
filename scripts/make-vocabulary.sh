#!/usr/bin/env bash
# Trains the built-in vocabulary (data/vocabulary/wh20.vocab) of the word-based
# recogniser: `mvkp vocab train` over OpenCV sample images (Debian opencv-doc)
# that no evaluation, test or sample target uses: not the Oxford / HPatches
# scenes (graf, leuven), the box pair, the samples/ images or the images of
# fetch-eval-images.sh.
#   scripts/make-vocabulary.sh [MVKP] [OUT] [WORDS]
set -euo pipefail
mvkp=${1:-build/mvkp}
out=${2:-data/vocabulary/wh20.vocab}
words=${3:-1024}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
( cd "$tmp" && apt-get download opencv-doc >/dev/null )
dpkg -x "$tmp"/opencv-doc*.deb "$tmp/x"
d="$tmp/x/usr/share/doc/opencv-doc/examples/data"
imgs=()
for f in Blender_Suzanne1.jpg HappyFish.jpg aloeL.jpg apple.jpg basketball1.png blox.jpg cards.png chicky_512.png \
         ela_original.jpg left.jpg orange.jpg pca_test1.jpg rubberwhale1.png smarties.png squirrel_cls.jpg stuff.jpg \
         sudoku.png licenseplate_motion.jpg notes.png pic1.png pic3.png pic5.png; do
  imgs+=("$d/$f")
done
mkdir -p "$(dirname "$out")"
"$mvkp" vocab train "${imgs[@]}" -o "$out" --words "$words" --locations 1000 --vocab-seed 1
