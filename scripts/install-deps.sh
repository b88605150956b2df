#!/usr/bin/env bash
# Installs the Debian 12 packages mvkp needs to build, test and run its demo.
# Idempotent: only missing packages are installed; uses sudo when not root.
set -euo pipefail
pkgs=(
  build-essential cmake pkg-config
  libopencv-dev            # imgcodecs, imgproc, features2d, calib3d (OpenCV 4.6)
  libjpeg-dev libpng-dev   # strict JPEG/PNG decoding (corrupt data is an error, not grey pixels)
  libgtest-dev googletest  # unit tests
  libcli11-dev             # command line
  nlohmann-json3-dev       # JSON output
  libfaiss-dev libhnswlib-dev  # nearest-neighbour baselines of bench/mvkp_bench_knn (optional there)
  libsqlite3-dev           # target database (src/mvkp/db)
  libcpp-httplib-dev       # mvkp serve (museum guide server)
  libssl-dev openssl       # mvkp serve --cert/--key (HTTPS); openssl makes the test certificates
  libgdal-dev              # GeoTIFF DSM/nDSM and orthophoto input (src/mvkp/geo, issue 8)
  nodejs                   # web client checks (tests/serve_api_test.py)
  chromium                 # web client in a real browser (tests/e2e, CTest web_e2e)
  python3 python3-numpy python3-opencv  # evaluation scripts (eval_pairs.py, contract-check)
  pybind11-dev python3-dev python3-pytest  # Python module `mvkp` (python/) and its tests
  doxygen                  # API reference (make docs)
  dpkg-dev fakeroot        # make deb (CPack DEB generator, dpkg-shlibdeps)
  clang-14 libclang-rt-14-dev llvm-14  # make sanitize / make fuzz: ASan, UBSan, libFuzzer, llvm-symbolizer
)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#pkgs[@]} packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
