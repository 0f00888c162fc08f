#!/bin/sh
# Renders docs/figures/smoothing.png, the analogue of the paper's Figures 1 and 12b: the shared CT
# head (headsq, isovalue 500: the skin) as data, smoothed below the data (--smooth 1), smoothed
# from a coarse level (--smooth-from 2: the data on every 4th sample only), and smoothed from that
# level inside a region only (the head's right half in data index x ≥ 32), the data's own values
# outside it, one conforming surface. Every panel is the full-resolution cut (--full).
# Tools: progiso (a release build), python3 and POV-Ray 3.7 (Debian: apt-get install povray).
#
#   docs/figures/smoothing.sh [PROGISO] [DATA_DIR]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
progiso=${1:-$root/build/release/apps/progiso/progiso}
data=${2:-${PROGISO_DATA_DIR:-$root/../shared/data}}
command -v povray >/dev/null || { echo "smoothing.sh: povray not found (apt-get install povray)" >&2; exit 1; }
[ -x "$progiso" ] || { echo "smoothing.sh: $progiso is not an executable (build the release preset)" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
head="$data/headsq_64x64x93_int16le.raw --dims 64,64,93 --type i16 --spacing 3.2,3.2,1.5"
panel() {  # name, options
  name=$1
  shift
  # shellcheck disable=SC2086 # $head is a list of arguments
  "$progiso" extract $head --iso 500 --full "$@" -o "$work/$name.ply" --stats-json "$work/$name.json"
  python3 "$here/ply2pov.py" "$work/$name.ply" "$name" > "$work/$name.inc"
}
panel Data
panel Below --smooth 1
panel Coarse --smooth 1 --smooth-from 1
panel Region --smooth 1 --smooth-from 1 --smooth-region 32,0,0,63,63,92
cp "$here/smoothing.pov" "$work/"
(cd "$work" && povray -D +W1600 +H330 +A0.2 +Q9 +Ismoothing.pov +Osmoothing.png >povray.log 2>&1) ||
  { cat "$work/povray.log" >&2; exit 1; }
cp "$work/smoothing.png" "$here/smoothing.png"
echo "wrote $here/smoothing.png"
