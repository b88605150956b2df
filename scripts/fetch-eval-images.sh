#!/usr/bin/env bash
# Extracts held-out evaluation targets (never tuned on) from Debian packages:
# opencv-doc (OpenCV sample images, BSD) and python3-skimage (scikit-image data,
# BSD/public domain). Writes them to ${1:-out/eval-images}.
set -euo pipefail
dest=${1:-out/eval-images}
mkdir -p "$dest"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
( cd "$tmp" && apt-get download opencv-doc python3-skimage >/dev/null )
for deb in "$tmp"/*.deb; do dpkg -x "$deb" "$tmp/x"; done
o="$tmp/x/usr/share/doc/opencv-doc/examples/data"
s="$tmp/x/usr/lib/python3/dist-packages/skimage/data"
for f in "$o/messi5.jpg" "$o/butterfly.jpg" "$o/aero1.jpg" "$o/home.jpg" "$o/board.jpg" "$o/lena.jpg" \
         "$s/chelsea.png" "$s/rocket.jpg" "$s/camera.png" "$s/motorcycle_left.png" "$s/hubble_deep_field.jpg" "$s/page.png"; do
  [ -f "$f" ] && cp "$f" "$dest/"
done
ls "$dest"
