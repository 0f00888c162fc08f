#!/usr/bin/env bash
# Installs progiso's build and test dependencies from Debian 12's packages (run as root, or
# with sudo available). Packages already present are not fetched again.
#
#   scripts/install-deps.sh           what the README's two commands need
#   scripts/install-deps.sh --fuzz    also clang's libFuzzer runtime (scripts/fuzz.sh)
#   scripts/install-deps.sh --peers   also VTK, the peer the benchmarks compare with
#                                     (bench/peer_bench.cpp; a large download)
set -euo pipefail
packages=(cmake ninja-build g++ clang-format pkg-config libgtest-dev libgmock-dev libbenchmark-dev
          libteem-dev libnifti2-dev libdcmtk-dev zlib1g-dev libpng-dev libtiff-dev libopenjp2-7-dev libcgal-dev libgmp-dev libmpfr-dev libboost-dev
          libblosc-dev libzstd-dev nlohmann-json3-dev python3-zarr python3-numcodecs
          libhdf5-dev python3-h5py
          libopenmpi-dev openmpi-bin
          libtbb-dev python3-mrcfile python3-dev python3-numpy pybind11-dev python3-pytest
          python3-skimage chromium)
for option in "$@"; do
  case "$option" in
    --fuzz) packages+=(clang libclang-rt-14-dev python3) ;;
    --peers) packages+=(libvtk9-dev) ;;
    *) echo "install-deps: unknown option $option (expected --fuzz or --peers)" >&2; exit 2 ;;
  esac
done
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm for the viewer's JavaScript, unless a Node.js is installed already.
command -v npm > /dev/null || missing+=(nodejs npm)
sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
else
  echo "install-deps: installing ${missing[*]}"
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
# The viewer's page (three.js) and its tests' tools (playwright-core, gltf-validator), from the
# npm registry at the versions web/package-lock.json pins; again only when the lock changed.
web="$(cd "$(dirname "$0")/.." && pwd)/web"
if ! cmp -s "$web/package-lock.json" "$web/node_modules/.progiso-lock"; then
  echo "install-deps: npm ci in web/"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error &&
   cp package-lock.json node_modules/.progiso-lock)
fi
