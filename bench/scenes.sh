#!/usr/bin/env bash
# The surgical scenes' step times as bench rows: each scene (examples/, docs/scenes.md) run to
# its end in accurate and real-time mode on 1 and 2 threads, its per-step median and maximum,
# and its events (a cut's growth, a tear's) appended to one CSV. The examples take the flags.
#
#   bash bench/scenes.sh BUILD_DIR CSV [scene ...]     (default: all five)
#
# Run through `bash cmake/setup.sh bench scenes`, which builds the examples first.
set -euo pipefail
build=$1 csv=$2
shift 2
scenes=("$@")
[ ${#scenes[@]} -eq 0 ] && scenes=(fat_grasp vessel_twist liver_cage liver_cut sheet_tear)
rm -f "$csv"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for scene in "${scenes[@]}"; do
  for mode in accurate realtime; do
    for threads in 1 2; do
      echo "bench/scenes.sh: $scene, $mode, $threads thread(s)"
      # One frame at the end only: the rows time the steps, not the output.
      "$build/examples/$scene" --mode "$mode" --threads "$threads" --every 100000 --out "$out" --csv "$csv" |
        grep -E "^per step|median" || true
    done
  done
done
echo "bench/scenes.sh: rows in $csv"
column -s, -t < "$csv"
