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
echo "== 6. the envelope (issue 18): small, steep and dim views as a camera sees them, mvkp and SIFT on the same frames"
"$mvkp" eval sweep "$here/samples/starry_night.jpg" --background "$here/samples/building.jpg" "$here/samples/fruits.jpg" \
  "$here/samples/baboon.jpg" --per-target 3 --methods mvkp,sift --size-edges 60,110,200,400 --tilt-edges 0,40,60,75 \
  --table-sizes 60-110,110-200,200-400 --table-tilts 0-40,40-60,60-75 --label demo --save-frames -o "$out/sweep"
"$mvkp" match "$out/starry_night.mvkp" "$out"/sweep/frames/frame_0000[0-2].png "$out"/sweep/frames/frame_0001[5-7].png \
  --draw "$out/envelope.png" >/dev/null
echo
echo "drawings: $out/match-*.png   (green outline = found target, green dots = inliers)"
echo "          $out/envelope-*.png (the smallest and the steepest sweep frames; curves: $out/sweep/{size,tilt}.svg)"
echo "          $out/quality.png   (white plus signs = the view tracks a model keeps)"
