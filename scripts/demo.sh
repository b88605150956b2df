#!/usr/bin/env bash
# The demo: train a target from one image, make cluttered test frames of it
# with known geometry, find it in each, and draw the results.
set -euo pipefail
mvkp=${1:-build/mvkp}
here=$(cd "$(dirname "$0")/.." && pwd)
out=${DEMO_OUT:-$here/out/demo}
mkdir -p "$out"
echo "== 0. how good is it as a target? (score, reasons, expected detection rate)"
"$mvkp" quality "$here/samples/starry_night.jpg" --draw "$out/quality.png"
echo
echo "== 1. train a target from one image (samples/starry_night.jpg)"
"$mvkp" train "$here/samples/starry_night.jpg" -o "$out/starry_night.mvkp"
echo
echo "== 2. synthesise 6 test frames: random viewpoint, clutter, light, blur, noise (known homographies)"
"$mvkp" synth "$here/samples/starry_night.jpg" --n 6 --seed 7 --target-size 0 \
  --background "$here/samples/fruits.jpg" -o "$out/frames"
echo
echo "== 3. find the target in each frame"
"$mvkp" match "$out/starry_night.mvkp" "$out"/frames/view_*.png --draw "$out/match.png"
echo
echo "== 4. accuracy against the known homographies, with OpenCV SIFT and ORB on the same frames"
"$mvkp" eval "$out/frames/manifest.txt" --baselines sift,orb
echo
echo "== 5. speed against OpenCV SIFT and ORB on the same frames (single thread)"
"$mvkp" bench "$here/samples/starry_night.jpg" "$out"/frames/view_*.png --repeat 3 --train-repeat 1
echo
echo "drawings: $out/match-*.png   (green outline = found target, green dots = inliers)"
echo "          $out/quality.png   (white plus signs = the view tracks a model keeps)"
