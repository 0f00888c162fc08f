#!/usr/bin/env bash
# Runs the same matrix of `progiso` commands with two builds of the command and compares what
# they write, byte for byte: a refactoring must leave the command's behaviour unchanged.
#
#   scripts/compare-outputs.sh OLD_PROGISO NEW_PROGISO [DATA_DIR]
#
# DATA_DIR defaults to ../shared/data beside the repository (or $PROGISO_DATA_DIR). For every
# volume and image there, at its suggested isovalues, and for the built-in demo volume, it runs
# the deterministic modes (--full and --error on 1 and 2 threads, --max-triangles on one: a
# budget's cut on more threads depends on the order the tasks finish; PLY, OBJ, STL, SVG;
# --normals, --world, smoothing; contours) and a few inputs that must be refused.
# Compared: every output file byte for byte, the exit status, stderr, and the --stats-json
# file with its timing fields (*_ms, *seconds*) and work counters removed. Deadline runs (--time-ms) depend on
# the clock, so they are not compared. Exits 1 on the first difference, printing it.
set -euo pipefail
old=$(realpath "$1")
new=$(realpath "$2")
root=$(cd "$(dirname "$0")/.." && pwd)
data=${3:-${PROGISO_DATA_DIR:-$root/../shared/data}}
[ -d "$data" ] || { echo "compare-outputs: no data directory at $data" >&2; exit 2; }
data=$(realpath "$data")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

runs=0
# run NAME OUTPUT-SUFFIXES -- ARGS...: runs both builds in their own folders (the same
# relative output names, so messages that quote them match) and compares.
run() {
  local name=$1
  shift
  local outs=()
  while [ "$1" != "--" ]; do outs+=("$1"); shift; done
  shift
  local side bin
  for side in old new; do
    bin=$old
    [ "$side" = new ] && bin=$new
    mkdir -p "$work/$side"
    (cd "$work/$side" && rm -rf ./* && set +e && "$bin" "$@" >stdout 2>stderr; echo $? >status)
  done
  local f
  for f in status stderr "${outs[@]}"; do
    if [ -e "$work/old/$f" ] || [ -e "$work/new/$f" ]; then
      if [ "$f" = stats.json ]; then
        for side in old new; do
          # Timings, and the smoothed field's lazily computed sample count (how many samples
          # the threads happened to compute, not an output), are left out.
          grep -vE '_ms"|seconds"' "$work/$side/$f" |
            sed -E 's/"subdivided_samples": [0-9]+, //' >"$work/$side/$f.stripped" || true
        done
        cmp -s "$work/old/$f.stripped" "$work/new/$f.stripped" || {
          echo "DIFFERENT $name: $f"; diff "$work/old/$f.stripped" "$work/new/$f.stripped" | head; exit 1; }
      elif [ -d "$work/old/$f" ]; then
        diff -r "$work/old/$f" "$work/new/$f" >/dev/null || { echo "DIFFERENT $name: $f/"; exit 1; }
      else
        cmp "$work/old/$f" "$work/new/$f" || { echo "DIFFERENT $name: $f"; exit 1; }
      fi
    fi
  done
  runs=$((runs + 1))
}

# file dims type isovalues [spacing]
volumes=(
  "bucky_32x32x32_uint8.raw 32,32,32 u8 51,128"
  "nucleon_41x41x41_uint8.raw 41,41,41 u8 60,140"
  "neghip_66x66x66_uint8.raw 66,66,66 u8 30,64,128"
  "hipip_68x68x68_uint8.raw 68,68,68 u8 128,30,200"
  "headsq_64x64x93_int16le.raw 64,64,93 i16 500,1150 3.2,3.2,1.5"
  "brainsmall_128x128x84_uint8.raw 128,128,84 u8 30,50"
)
for entry in "${volumes[@]}"; do
  read -r file dims type isos spacing <<<"$entry"
  [ -f "$data/$file" ] || { echo "compare-outputs: $file missing, skipped"; continue; }
  base=(extract "$data/$file" --dims "$dims" --type "$type")
  [ -n "${spacing:-}" ] && base+=(--spacing "$spacing")
  IFS=, read -ra list <<<"$isos"
  for w in "${list[@]}"; do
    for t in 1 2; do
      run "$file $w full t$t" out.ply stats.json -- "${base[@]}" --iso "$w" -o out.ply --threads "$t" --stats-json stats.json
      run "$file $w error t$t" out.obj stats.json -- "${base[@]}" --iso "$w" -o out.obj --error 2 --threads "$t" --stats-json stats.json
    done
    run "$file $w triangles" out.ply stats.json -- "${base[@]}" --iso "$w" -o out.ply --max-triangles 5000 --threads 1 --stats-json stats.json
    run "$file $w stl" out.stl -- "${base[@]}" --iso "$w" -o out.stl
    run "$file $w normals" out.ply -- "${base[@]}" --iso "$w" -o out.ply --normals
    run "$file $w normals obj" out.obj -- "${base[@]}" --iso "$w" -o out.obj --normals --error 4
    run "$file $w smooth" out.ply stats.json -- "${base[@]}" --iso "$w" -o out.ply --smooth 1 --stats-json stats.json
    run "$file $w smooth-from" out.ply -- "${base[@]}" --iso "$w" -o out.ply --smooth-from 1 --error 1
  done
done

# A NRRD header over a raw file, for --world and the header path.
if [ -f "$data/headsq_64x64x93_int16le.raw" ]; then
  mkdir -p "$work/inputs"
  cat >"$work/inputs/headsq.nhdr" <<EOF
NRRD0004
type: short
dimension: 3
sizes: 64 64 93
space: left-posterior-superior
space directions: (0,3.2,0) (-3.2,0,0) (0,0,1.5)
space origin: (10,20,30)
encoding: raw
endian: little
data file: $data/headsq_64x64x93_int16le.raw
EOF
  run "nhdr world" out.ply -- extract "$work/inputs/headsq.nhdr" --iso 500 -o out.ply --world
  run "nhdr plain" out.obj stats.json -- extract "$work/inputs/headsq.nhdr" --iso 1150 -o out.obj --error 8 --stats-json stats.json
fi

for t in 1 2; do
  run "demo t$t" demo.ply stats.json -- extract --demo -o demo.ply --threads "$t" --stats-json stats.json
  run "demo error t$t" demo.ply -- extract --demo -o demo.ply --error 0.01 --threads "$t"
done
run "demo triangles" demo.ply -- extract --demo -o demo.ply --max-triangles 20000 --threads 1
run "demo normals" demo.obj -- extract --demo -o demo.obj --normals --iso 0.3

# Images: file isovalues.
images=(
  "camera_512x512.pgm 64,128,192"
  "coins_384x303.pgm 128"
  "jacksboro_dem_403x344_u16.pgm 300,600,900"
)
for entry in "${images[@]}"; do
  read -r file isos <<<"$entry"
  [ -f "$data/$file" ] || { echo "compare-outputs: $file missing, skipped"; continue; }
  run "$file full" out.obj stats.json -- contour "$data/$file" --iso "$isos" -o out.obj --stats-json stats.json
  run "$file svg" out.svg -- contour "$data/$file" --iso "$isos" -o out.svg
  run "$file error" out.obj stats.json -- contour "$data/$file" --iso "$isos" -o out.obj --error 4 --stats-json stats.json
  run "$file segments" out.obj -- contour "$data/$file" --iso "$isos" -o out.obj --max-segments 3000
  run "$file frames" out.svg frames -- contour "$data/$file" --iso "${isos%%,*}" -o out.svg --error 8 --frames frames
  run "$file smooth" out.obj -- contour "$data/$file" --iso "$isos" -o out.obj --smooth 1
done

# Refusals: the exit status and the one line on stderr must not change.
run "no args" -- extract
run "help" -- --help
run "missing input" out.ply -- extract does-not-exist.nrrd --iso 1 -o out.ply
run "bad dims" out.ply -- extract "$data/bucky_32x32x32_uint8.raw" --dims 33,32,32 --type u8 --iso 1 -o out.ply
run "bad mode" out.ply -- extract --demo -o out.ply --error -1
run "bad iso" out.ply -- extract --demo -o out.ply --iso nan
run "bad contour" out.obj -- contour "$data/bucky_32x32x32_uint8.raw" --iso 1 -o out.obj
echo "compare-outputs: $runs runs, every output identical"
