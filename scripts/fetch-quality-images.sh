#!/usr/bin/env bash
# Assembles the validation set for the target quality score (how well an image
# will work as a planar AR target, like ARCore's arcoreimg score): real and
# generated images from great to hopeless targets, by category
#   painting    scans of paintings and prints (GCompris "details" and "paintings"
#               activities, gcompris-qt-data; the puzzle pieces are reassembled)
#   photo       detailed photographs (python3-skimage, gcompris-qt-data)
#   poster      picture plus large text (opencv-doc box.png; three composed here)
#   logo        few flat shapes (opencv-doc, desktop-base Debian logos, skimage
#               horse; one drawn here)
#   text        text only (skimage page/handwriting, opencv-doc book page; two drawn here)
#   repetitive  brick, grass, gravel, chessboard, a tiled motif, a woven grid
#   uniform     flat grey, smooth gradient, flat colour with faint noise, a
#               blurred low-contrast painting
#   fetch-quality-images.sh [DEST]      (default out/quality-images)
# Writes DEST/*.png (longest side 400..1200 px: bigger ones downscaled with
# INTER_AREA, smaller ones upscaled with INTER_CUBIC) and DEST/images.csv with
# file,category,source,license (fields contain no commas or quotes).
# Packages are fetched with `apt-get download` and unpacked with dpkg-deb into
# a temporary folder; nothing is installed. Set QUALITY_IMAGES_DEBS=DIR to use
# already downloaded .deb files from DIR instead. Decoding and drawing use
# /usr/bin/python3 with numpy and cv2 (python3-opencv, built with WebP).
# Deterministic: re-running rewrites the same files.
set -euo pipefail
dest=${1:-out/quality-images}
py=${PYTHON:-/usr/bin/python3}
pkgs=(gcompris-qt-data python3-skimage opencv-doc desktop-base)
declare -A want=(  # only these parts of each package are unpacked
  [gcompris-qt-data]='./usr/share/gcompris-qt/rcc/details.rcc ./usr/share/gcompris-qt/rcc/paintings.rcc'
  [python3-skimage]='./usr/lib/python3/dist-packages/skimage/data/*.png ./usr/lib/python3/dist-packages/skimage/data/*.jpg'
  [opencv-doc]='./usr/share/doc/opencv-doc/examples/data/*.png ./usr/share/doc/opencv-doc/examples/data/*.jpg'
  [desktop-base]='./usr/share/plymouth/themes/softwaves/logo.png ./usr/share/desktop-base/debian-logos/*.png'
)

die() { echo "fetch-quality-images: $*" >&2; exit 1; }
command -v dpkg-deb >/dev/null || die "needs dpkg-deb (Debian)"
"$py" -c 'import numpy, cv2' 2>/dev/null ||
  die "needs $py with numpy and cv2: apt-get install python3-numpy python3-opencv (or run scripts/install-deps.sh)"

shopt -s nullglob
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/debs" "$tmp/root"
versions=()
for p in "${pkgs[@]}"; do
  deb=""
  if [ -n "${QUALITY_IMAGES_DEBS:-}" ]; then
    cached=("$QUALITY_IMAGES_DEBS/${p}"_*.deb)
    if [ ${#cached[@]} -gt 0 ]; then deb=${cached[-1]}; fi
  fi
  if [ -z "$deb" ]; then
    echo "fetch-quality-images: apt-get download $p"
    if ! (cd "$tmp/debs" && apt-get download "$p" >"$tmp/apt.log" 2>&1); then
      cat "$tmp/apt.log" >&2
      die "apt-get download $p failed (run 'apt-get update' first; needs the Debian archive)"
    fi
    got=("$tmp/debs/${p}"_*.deb)
    [ ${#got[@]} -gt 0 ] || die "apt-get download $p left no .deb"
    deb=${got[0]}
  fi
  read -ra globs <<<"${want[$p]}"
  dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$tmp/root" --wildcards "${globs[@]}" ||
    die "cannot unpack ${globs[*]} from $deb"
  versions+=("$p=$(dpkg-deb -f "$deb" Version)")
done

mkdir -p "$dest"
# (libpng's warnings about the ICC profiles of some sample PNGs are dropped)
"$py" - "$tmp/root" "$dest" "${versions[@]}" 2> >(grep -v '^libpng warning' >&2) <<'PY'
import csv, os, re, struct, sys, zlib
import numpy as np
import cv2

root, dest = sys.argv[1], sys.argv[2]
ver = dict(a.split("=", 1) for a in sys.argv[3:])
rows = []


def fail(msg):
    sys.exit("fetch-quality-images: " + msg)


def clean(s):
    return re.sub(r"\s+", " ", s.replace(",", " -").replace('"', "")).strip()


def src(pkg, path, note=""):
    return f"Debian {pkg} {ver[pkg]}: {path}" + (f" ({note})" if note else "")


def path_in(pkg_rel):
    p = os.path.join(root, pkg_rel)
    if not os.path.isfile(p):
        fail(f"expected file missing from the unpacked packages: /{pkg_rel}")
    return p


def read(pkg_rel, flags=cv2.IMREAD_UNCHANGED):
    im = cv2.imread(path_in(pkg_rel), flags)
    if im is None:
        fail(f"cannot decode /{pkg_rel}")
    return im


def decode(data, what):
    im = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if im is None:
        fail(f"cannot decode {what} (cv2 without WebP support?)")
    return im


def flatten(im, bg=(255, 255, 255)):
    """BGR(A)/grey -> BGR, alpha composited over a flat background."""
    if im.ndim == 2:
        return cv2.cvtColor(im, cv2.COLOR_GRAY2BGR)
    if im.shape[2] == 3:
        return im
    a = im[:, :, 3:4].astype(np.float32) / 255
    out = im[:, :, :3].astype(np.float32) * a + np.float32(bg) * (1 - a)
    return np.clip(out + 0.5, 0, 255).astype(np.uint8)


def fit(im, lo=400, hi=1200):
    h, w = im.shape[:2]
    m = max(h, w)
    if m > hi:
        s, interp = hi / m, cv2.INTER_AREA
    elif m < lo:
        k = -(-lo // m)  # integer factor when it fits, else exactly lo
        s, interp = (k if m * k <= hi else lo / m), cv2.INTER_CUBIC
    else:
        return im
    return cv2.resize(im, (max(1, round(w * s)), max(1, round(h * s))), interpolation=interp)


def save(name, im, category, source, license):
    im = fit(im)
    if not cv2.imwrite(os.path.join(dest, name), im):
        fail(f"cannot write {dest}/{name}")
    rows.append((name, category, clean(source), clean(license)))


# ---------------------------------------------------------------- Qt .rcc reader
def rcc_files(rel):
    """{path: bytes} of a Qt resource file (format versions 1-3)."""
    b = open(path_in(rel), "rb").read()
    if b[:4] != b"qres":
        fail(f"/{rel} is not a Qt resource file")
    version, tree, data, names = struct.unpack(">IIII", b[4:20])
    node_size = 14 if version == 1 else 22
    out = {}

    def name(off):
        (n,) = struct.unpack(">H", b[names + off:names + off + 2])
        return b[names + off + 6:names + off + 6 + 2 * n].decode("utf-16-be")

    def walk(i, prefix):
        o = tree + i * node_size
        noff, flags = struct.unpack(">IH", b[o:o + 6])
        nm = name(noff) if i else ""
        if flags & 2:  # directory
            count, first = struct.unpack(">II", b[o + 6:o + 14])
            for c in range(count):
                walk(first + c, prefix + nm + "/")
            return
        (doff,) = struct.unpack(">I", b[o + 10:o + 14])
        (size,) = struct.unpack(">I", b[data + doff:data + doff + 4])
        raw = b[data + doff + 4:data + doff + 4 + size]
        if flags & 4:
            fail(f"/{rel}: zstd-compressed entries are not supported")
        if flags & 1:
            raw = zlib.decompress(raw[4:])
        out[prefix + nm] = raw

    walk(0, "")
    return out


def readme_license(readme, fname):
    for block in readme.split("\n\n"):
        if fname in block:
            lic = re.search(r"^License:\s*(.+)$", block, re.M)
            com = re.search(r"^Comment:\s*(.+)$", block, re.M)
            return (lic.group(1) if lic else "?") + (f" - {com.group(1).strip()}" if com else "")
    fail(f"no licence entry for {fname} in the GCompris README")


G = "usr/share/gcompris-qt/rcc/"

# ------------------------------------------------------------------ paintings
det = rcc_files(G + "details.rcc")
det_dir = "/gcompris/src/activities/details/resource/"
det_readme = det[det_dir + "image/README"].decode()
det_titles = {}
for k, v in det.items():
    if "/board/" in k:
        q = v.decode()
        t = re.search(r'qsTr\("([^"]*)"\)', q)
        p = re.search(r'"pixmapfile" : "image/([^"]+)"', q)
        if t and p:
            det_titles[p.group(1)] = t.group(1)


def details_image(stem):
    fname = stem + "_background.webp"
    key = det_dir + "image/" + fname
    if key not in det:
        fail(f"{fname} not in {G}details.rcc")
    return decode(det[key], fname), fname, det_titles.get(fname, stem), readme_license(det_readme, fname)


for stem, out in [("Van_Gogh_The_Night_Cafe", "vangogh_night_cafe"),
                  ("PortraitOfPereTanguy", "vangogh_pere_tanguy"),
                  ("Eglise_dAuvers-sur-Oise", "vangogh_church_auvers"),
                  ("Gogh4", "vangogh_cafe_terrace"),
                  ("VincentVanGogh0013", "vangogh_painter_on_road"),
                  ("VincentVanGogh0019", "vangogh_harvest")]:
    im, fname, title, lic = details_image(stem)
    save(f"painting_{out}.png", flatten(im), "painting",
         src("gcompris-qt-data", f"/{G}details.rcc:{fname}", title), lic)

pnt = rcc_files(G + "paintings.rcc")
pnt_dir = "/gcompris/src/activities/paintings/resource/"
pnt_readme = pnt[pnt_dir + "image/README"].decode()
pnt_lic = re.search(r"^License:\s*(.+)$", pnt_readme, re.M).group(1)
pnt_boards = {}
for k, v in pnt.items():
    if "/board/" in k:
        q = v.decode()
        pieces = re.findall(r'"pixmapfile" : "(image/[^"]+\.webp)",\s*"x" : "([\d.]+)",\s*"y" : "([\d.]+)"', q)
        if pieces:
            pnt_boards[k] = (re.search(r'qsTr\("([^"]*)"\)', q).group(1), pieces)


def assemble(prefix):
    """Lay the jigsaw pieces of one painting at their solved positions."""
    for board, (title, pieces) in sorted(pnt_boards.items()):
        if os.path.basename(pieces[0][0]).startswith(prefix):
            break
    else:
        fail(f"no board with pieces {prefix}* in {G}paintings.rcc")
    W, H = 702, 515  # board size declared in the board files
    can = np.full((H, W, 3), 255, np.float32)
    cov = np.zeros((H, W), np.float32)
    for p, x, y in pieces:
        im = decode(pnt[pnt_dir + p], p)
        if im.ndim == 2:
            im = cv2.cvtColor(im, cv2.COLOR_GRAY2BGR)
        if im.shape[2] == 3:
            im = np.dstack([im, np.full(im.shape[:2], 255, np.uint8)])
        h, w = im.shape[:2]
        x0, y0 = int(round(float(x) * W - w / 2)), int(round(float(y) * H - h / 2))
        xa, ya, xb, yb = max(x0, 0), max(y0, 0), min(x0 + w, W), min(y0 + h, H)
        sub = im[ya - y0:yb - y0, xa - x0:xb - x0].astype(np.float32)
        a = sub[:, :, 3:4] / 255
        can[ya:yb, xa:xb] = can[ya:yb, xa:xb] * (1 - a) + sub[:, :, :3] * a
        cov[ya:yb, xa:xb] += a[:, :, 0]
    ys, xs = np.where(cov > 0.5)
    out = can[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
    return np.clip(out + 0.5, 0, 255).astype(np.uint8), board.rsplit("/", 1)[1], title


great_wave = None
for prefix, out in [("GreatWave_", "hokusai_great_wave"),
                    ("kandinky_", "kandinsky_composition_viii"),
                    ("MonaLisa_", "leonardo_mona_lisa"),
                    ("PieterBruegel_", "bruegel_harvesters"),
                    ("HiroshigeInokashiraSnow_", "hiroshige_inokashira_snow")]:
    im, board, title = assemble(prefix)
    if prefix == "GreatWave_":
        great_wave = im
    save(f"painting_{out}.png", im, "painting",
         src("gcompris-qt-data", f"/{G}paintings.rcc:{board} + {prefix}*.webp",
             f"{title}; jigsaw pieces reassembled"),
         f"{pnt_lic} (GCompris/WebMuseum scan; artwork public domain)")

# --------------------------------------------------------------------- photos
SK = "usr/lib/python3/dist-packages/skimage/data/"
OC = "usr/share/doc/opencv-doc/examples/data/"
OC_LIC = "Apache-2.0 AND BSD-3-Clause (opencv-doc debian/copyright Files: *)"
save("photo_chelsea_cat.png", read(SK + "chelsea.png", cv2.IMREAD_COLOR), "photo",
     src("python3-skimage", "/" + SK + "chelsea.png"), "CC0 (Stefan van der Walt)")
save("photo_coffee.png", read(SK + "coffee.png", cv2.IMREAD_COLOR), "photo",
     src("python3-skimage", "/" + SK + "coffee.png"), "CC0 (Rachel Michetti)")
im, fname, title, lic = details_image("Neuschwanstein")
save("photo_neuschwanstein.png", flatten(im), "photo",
     src("gcompris-qt-data", f"/{G}details.rcc:{fname}", title), lic)

# ------------------------------------------------------------------- drawing
F, FB, FS = cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_TRIPLEX


def text(img, s, org, scale, color, thick, font=F, center=False):
    if center:
        (tw, _), _ = cv2.getTextSize(s, font, scale, thick)
        org = (org[0] - tw // 2, org[1])
    cv2.putText(img, s, org, font, scale, color, thick, cv2.LINE_AA)


def cover(im, w, h):
    s = max(w / im.shape[1], h / im.shape[0])
    r = cv2.resize(im, (round(im.shape[1] * s), round(im.shape[0] * s)), interpolation=cv2.INTER_AREA)
    y, x = (r.shape[0] - h) // 2, (r.shape[1] - w) // 2
    return r[y:y + h, x:x + w].copy()


GEN = "generated by scripts/fetch-quality-images.sh"
GEN_LIC = "same as this repository (generated)"

# -------------------------------------------------------------------- posters
box = read(OC + "box.png", cv2.IMREAD_COLOR)
save("poster_cookie_box.png", box, "poster",
     src("opencv-doc", "/" + OC + "box.png", "photo of a product box: pictures plus text"), OC_LIC)

p = np.full((850, 600, 3), (60, 30, 20), np.uint8)  # navy
p[40:440, 30:570] = cover(great_wave, 540, 400)
text(p, "HOKUSAI", (300, 540), 2.6, (255, 255, 255), 6, FS, center=True)
text(p, "PRINTS OF EDO", (300, 600), 1.2, (120, 200, 245), 2, FB, center=True)
cv2.rectangle(p, (60, 640), (540, 646), (40, 120, 230), -1)
text(p, "CITY MUSEUM  3 MAY - 30 JUNE", (300, 700), 0.9, (255, 255, 255), 2, F, center=True)
for i, c in enumerate([(40, 120, 230), (80, 180, 250), (200, 160, 60)]):
    cv2.circle(p, (240 + 60 * i, 780), 20, c, -1, cv2.LINE_AA)
save("poster_exhibition.png", p, "poster",
     GEN + ": Great Wave reassembly (painting_hokusai_great_wave.png) with title text and shapes",
     f"{pnt_lic} (painting part) + generated text")

rocket = read(SK + "rocket.jpg", cv2.IMREAD_COLOR)
p = cover(rocket, 800, 560)
band = p[380:540].astype(np.float32) * 0.35
p[380:540] = band.astype(np.uint8)
text(p, "LAUNCH DAY", (40, 470), 2.4, (0, 215, 255), 7, FB)
text(p, "LIVE COVERAGE FROM 09:30 - PAD 40", (44, 520), 0.95, (255, 255, 255), 2, F)
cv2.rectangle(p, (600, 30), (770, 90), (40, 40, 220), -1)
text(p, "NEW", (685, 75), 1.3, (255, 255, 255), 3, FB, center=True)
save("poster_launch.png", p, "poster",
     GEN + ": skimage rocket.jpg (" + src("python3-skimage", "/" + SK + "rocket.jpg") + ") with headline band",
     "public domain (SpaceX photo) + generated text")

cat = read(SK + "chelsea.png", cv2.IMREAD_COLOR)
p = np.full((800, 600, 3), (0, 140, 255), np.uint8)  # orange
for y in range(0, 800, 80):
    cv2.rectangle(p, (0, y), (600, y + 12), (40, 170, 255), -1)
photo = cover(cat, 340, 340)
mask = np.zeros((340, 340), np.uint8)
cv2.circle(mask, (170, 170), 165, 255, -1, cv2.LINE_AA)
a = mask[:, :, None].astype(np.float32) / 255
roi = p[60:400, 130:470].astype(np.float32)
p[60:400, 130:470] = (roi * (1 - a) + photo * a).astype(np.uint8)
cv2.circle(p, (300, 230), 168, (255, 255, 255), 6, cv2.LINE_AA)
text(p, "SALE", (300, 560), 4.0, (255, 255, 255), 12, FB, center=True)
text(p, "-50% ON EVERYTHING", (300, 640), 1.3, (60, 30, 20), 3, FB, center=True)
text(p, "PET SHOP  12 MARKET ST", (300, 720), 0.9, (255, 255, 255), 2, F, center=True)
save("poster_sale.png", p, "poster",
     GEN + ": skimage chelsea.png (" + src("python3-skimage", "/" + SK + "chelsea.png") + ") in a circle on flat orange with large text",
     "CC0 (photo) + generated")

# ---------------------------------------------------------------------- logos
save("logo_opencv.png", flatten(read(OC + "opencv-logo.png")), "logo",
     src("opencv-doc", "/" + OC + "opencv-logo.png", "on white"), OC_LIC + "; OpenCV trademark")
DB = "usr/share/plymouth/themes/softwaves/logo.png"
DB_LIC = "GPL-3+ or CC-BY-SA-3.0 (desktop-base debian/copyright; Debian logo - SPI trademark)"
save("logo_debian_swirl.png", flatten(read(DB)), "logo", src("desktop-base", "/" + DB, "on white"), DB_LIC)
DW = "usr/share/desktop-base/debian-logos/logo-text-version-256.png"
w = read(DW)
bg = (81, 7, 215)  # Debian red
canvas = np.zeros((w.shape[0] + 120, w.shape[1] + 120, 4), np.uint8)
canvas[60:60 + w.shape[0], 60:60 + w.shape[1]] = w
save("logo_debian_wordmark.png", flatten(canvas, bg), "logo",
     src("desktop-base", "/" + DW, "white on flat Debian red"), DB_LIC)
save("logo_horse_silhouette.png", flatten(read(SK + "horse.png")), "logo",
     src("python3-skimage", "/" + SK + "horse.png"), "CC0 (Andreas Preuss - openclipart)")
save("logo_linux_wordmark.png", read(OC + "LinuxLogo.jpg", cv2.IMREAD_COLOR), "logo",
     src("opencv-doc", "/" + OC + "LinuxLogo.jpg"), OC_LIC)
p = np.full((500, 640, 3), 255, np.uint8)
for (cx, cy), c in zip([(190, 200), (320, 200), (450, 200)], [(200, 120, 0), (40, 40, 40), (60, 60, 220)]):
    cv2.circle(p, (cx, cy), 70, c, 18, cv2.LINE_AA)
text(p, "RINGO", (320, 400), 2.5, (40, 40, 40), 8, FB, center=True)
save("logo_rings_generated.png", p, "logo", GEN + ": three flat rings and a wordmark", GEN_LIC)

# ----------------------------------------------------------------------- text
save("text_scanned_page.png", read(SK + "page.png", cv2.IMREAD_GRAYSCALE), "text",
     src("python3-skimage", "/" + SK + "page.png", "scanned printed page"), "BSD-3-Clause (scikit-image data)")
save("text_handwriting.png", read(SK + "text.png", cv2.IMREAD_GRAYSCALE), "text",
     src("python3-skimage", "/" + SK + "text.png", "handwritten formulas on paper"),
     "public domain (Wikipedia File:Corner.png)")
save("text_book_page.png", read(OC + "imageTextN.png", cv2.IMREAD_COLOR), "text",
     src("opencv-doc", "/" + OC + "imageTextN.png", "printed book paragraph"), OC_LIC)
para = ("A good augmented reality target has many distinct corners spread "
        "over the whole picture and little repetition. Plain text is a poor "
        "target: the same few letter shapes recur everywhere and the page is "
        "mostly empty paper. Every line of this paragraph looks much like the "
        "next one when seen from a distance or at an angle, so features found "
        "in one place match many others and the pose cannot be trusted.").split()
p = np.full((600, 800, 3), 255, np.uint8)
lines, cur = [], ""
for word in para:
    cand = (cur + " " + word).strip()
    if cv2.getTextSize(cand, cv2.FONT_HERSHEY_COMPLEX, 0.75, 1)[0][0] > 700:
        lines.append(cur)
        cur = word
    else:
        cur = cand
lines.append(cur)
text(p, "On choosing image targets", (50, 70), 1.1, (0, 0, 0), 2, cv2.FONT_HERSHEY_COMPLEX)
for i, line in enumerate(lines):
    text(p, line, (50, 130 + 36 * i), 0.75, (20, 20, 20), 1, cv2.FONT_HERSHEY_COMPLEX)
save("text_paragraph_generated.png", p, "text", GEN + ": Hershey-font paragraph on white", GEN_LIC)
p = np.full((450, 800, 3), (235, 235, 235), np.uint8)
for i, s in enumerate(["PLATFORM 3", "NO ENTRY", "EXIT ->"]):
    text(p, s, (400, 130 + 130 * i), 2.6, (30, 30, 30), 7, FB, center=True)
save("text_sign_generated.png", p, "text", GEN + ": three lines of large sign lettering", GEN_LIC)

# ----------------------------------------------------------------- repetitive
for n, what in [("brick", "CC0 (cc0textures Bricks25)"), ("grass", "CC0 (DeviantArt linolafett Grass-01)"),
                ("gravel", "CC0 (cc0textures Gravel04)")]:
    save(f"repetitive_{n}.png", read(SK + f"{n}.png", cv2.IMREAD_GRAYSCALE), "repetitive",
         src("python3-skimage", "/" + SK + f"{n}.png"), what)
save("repetitive_chessboard.png", flatten(read(OC + "chessboard.png")), "repetitive",
     src("opencv-doc", "/" + OC + "chessboard.png", "calibration chessboard"), OC_LIC)
night, _, _, _ = details_image("Van_Gogh_The_Night_Cafe")
tile = flatten(night)[200:280, 40:120]  # 80x80 crop: a table with glasses
save("repetitive_tiled_motif.png", np.tile(tile, (6, 8, 1)), "repetitive",
     GEN + ": one 80x80 crop of painting_vangogh_night_cafe.png tiled 8x6 (wallpaper-like)",
     "public domain (Van Gogh via gcompris-qt-data)")
yy, xx = np.mgrid[0:600, 0:800].astype(np.float32)
warp = np.sin(xx * 2 * np.pi / 16) * (np.sin(yy * 2 * np.pi / 32) > 0)
weft = np.sin(yy * 2 * np.pi / 16) * (np.sin(xx * 2 * np.pi / 32) <= 0)
g = 128 + 60 * (warp + weft)
rng = np.random.default_rng(1)
g += rng.normal(0, 4, g.shape)
fabric = np.dstack([g * 0.55, g * 0.75, g]).clip(0, 255).astype(np.uint8)
save("repetitive_woven_fabric_generated.png", fabric, "repetitive",
     GEN + ": basket-weave pattern (period 32 px) with faint noise", GEN_LIC)

# -------------------------------------------------------------------- uniform
save("uniform_flat_grey.png", np.full((480, 640), 128, np.uint8), "uniform",
     GEN + ": flat grey 128", GEN_LIC)
gx = np.linspace(60, 200, 640, dtype=np.float32)[None, :]
gy = np.linspace(0, 30, 480, dtype=np.float32)[:, None]
save("uniform_gradient.png", (gx + gy).clip(0, 255).astype(np.uint8), "uniform",
     GEN + ": smooth diagonal grey gradient 60..230", GEN_LIC)
rng = np.random.default_rng(2)
col = np.float32([180, 120, 70])[None, None, :] + rng.normal(0, 3, (480, 640, 1)).astype(np.float32)
save("uniform_flat_colour_noise.png", col.clip(0, 255).astype(np.uint8), "uniform",
     GEN + ": flat steel blue with Gaussian noise sigma 3", GEN_LIC)
tanguy, _, _, _ = details_image("PortraitOfPereTanguy")
b = cv2.GaussianBlur(flatten(tanguy).astype(np.float32), (0, 0), 20)
b = b.mean() + (b - b.mean()) * 0.2
save("uniform_blurred_low_contrast.png", b.clip(0, 255).astype(np.uint8), "uniform",
     GEN + ": painting_vangogh_pere_tanguy.png Gaussian-blurred (sigma 20) at 20% contrast",
     "public domain (Van Gogh via gcompris-qt-data)")

# ------------------------------------------------------------------ manifest
with open(os.path.join(dest, "images.csv"), "w", newline="") as f:
    wr = csv.writer(f, lineterminator="\n")
    wr.writerow(["file", "category", "source", "license"])
    wr.writerows(rows)
counts = {}
for r in rows:
    counts[r[1]] = counts.get(r[1], 0) + 1
print(f"fetch-quality-images: {len(rows)} images in {dest}: "
      + " ".join(f"{k}={v}" for k, v in counts.items()))
PY
