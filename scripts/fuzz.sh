#!/usr/bin/env bash
# Builds progiso's libFuzzer harnesses (clang, AddressSanitizer + UBSan: the `fuzz` preset) and
# runs each for as long as asked.
#
#   scripts/fuzz.sh [SECONDS_PER_HARNESS] [HARNESS ...]     (default: 60 s, every harness)
#
# Harnesses: raw nrrd nifti metaimage vtk vti pvti dicom jpeg tiff mrc zarr hdf5 pgm png ply obj cli extract hierarchy (tests/fuzz/*_fuzz.cpp). Each starts from a working
# corpus in build/fuzz/corpus/<harness> (or $PROGISO_FUZZ_BUILD/corpus/<harness>, see below): the committed seeds and regressions
# (tests/fuzz/corpus/<harness>), plus crops of the real data in ../shared/data (or
# $PROGISO_DATA_DIR) made by tests/fuzz/make_seeds.py; the corpus grows across runs. An input
# that crashes a harness is written to build/fuzz/artifacts/<harness>/: copy it into
# tests/fuzz/corpus/<harness>/ so that every test build replays it from then on.
#
# Prints one line per harness (executions, executions per second, corpus size, crashes) and
# exits non-zero when any harness found a crash. Two harnesses run at a time ($PROGISO_FUZZ_JOBS).
set -euo pipefail
cd "$(dirname "$0")/.."

seconds="${1:-60}"
shift || true
harnesses=("$@")
[ ${#harnesses[@]} -gt 0 ] || harnesses=(raw nrrd nifti metaimage vtk vti pvti dicom jpeg tiff mrc zarr hdf5 pgm png ply obj cli extract hierarchy)
jobs="${PROGISO_FUZZ_JOBS:-2}"

./scripts/install-deps.sh --fuzz >/dev/null
# The harnesses come from the `fuzz` preset's tree, or from an already configured clang
# asan-ubsan tree named by $PROGISO_FUZZ_BUILD (CI reuses its sanitizer build this way).
work="${PROGISO_FUZZ_BUILD:-build/fuzz}"
if [ -z "${PROGISO_FUZZ_BUILD:-}" ]; then
  cmake --preset fuzz >/dev/null
elif [ ! -f "$work/CMakeCache.txt" ]; then
  echo "fuzz.sh: PROGISO_FUZZ_BUILD=$work is not a configured build tree" >&2
  exit 2
fi
targets=()
for h in "${harnesses[@]}"; do targets+=("progiso_fuzz_$h"); done
cmake --build "$work" --target "${targets[@]}" >/dev/null

data="${PROGISO_DATA_DIR:-../shared/data}"
seeds="$work/seeds"
rm -rf "$seeds"
if [ -d "$data" ]; then
  python3 tests/fuzz/make_seeds.py "$seeds" "$data"
else
  python3 tests/fuzz/make_seeds.py "$seeds"
fi

# libhdf5's own leaks on corrupt files, and nothing else (tests/fuzz/lsan.supp says which).
export LSAN_OPTIONS="suppressions=$PWD/tests/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"

run_one() {
  local h="$1"
  local corpus="$work/corpus/$h" artifacts="$work/artifacts/$h/" log="$work/logs/$h.log"
  mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
  cp -n tests/fuzz/corpus/"$h"/* "$corpus"/ 2>/dev/null || true
  cp -n "$seeds/$h"/* "$corpus"/ 2>/dev/null || true
  local status=0 extra=()
  # The HDF5 reader runs libhdf5 in child processes (forked: they inherit libFuzzer's malloc
  # hook, which would report a child's large request as the harness's own out-of-memory). The
  # harness's memory stays bounded by -rss_limit_mb; a child's by its own limit.
  [ "$h" = hdf5 ] && extra=(-malloc_limit_mb=1048576)
  "$work/tests/fuzz/progiso_fuzz_$h" "$corpus" -max_total_time="$seconds" \
      -artifact_prefix="$artifacts" -print_final_stats=1 -rss_limit_mb=2048 -timeout=20 \
      -max_len=262144 -close_fd_mask=3 "${extra[@]}" >"$log" 2>&1 || status=$?
  local execs rate size crashes
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  size=$(find "$corpus" -type f | wc -l)
  crashes=$(find "$artifacts" -type f | wc -l)
  printf 'fuzz %-5s %12s executions %8s/s  corpus %6s  crashes %s  (exit %s)\n' \
      "$h" "${execs:-?}" "${rate:-?}" "$size" "$crashes" "$status"
  [ "$status" -eq 0 ] && [ "$crashes" -eq 0 ]
}

failed=0
pids=()
names=()
for h in "${harnesses[@]}"; do
  run_one "$h" &
  pids+=($!)
  names+=("$h")
  if [ ${#pids[@]} -ge "$jobs" ]; then
    wait "${pids[0]}" || { failed=1; echo "fuzz ${names[0]}: FOUND A CRASH, see $work/logs/${names[0]}.log"; }
    pids=("${pids[@]:1}")
    names=("${names[@]:1}")
  fi
done
for i in "${!pids[@]}"; do
  wait "${pids[$i]}" || { failed=1; echo "fuzz ${names[$i]}: FOUND A CRASH, see $work/logs/${names[$i]}.log"; }
done
exit "$failed"
