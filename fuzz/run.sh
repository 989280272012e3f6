#!/usr/bin/env bash
# Builds the libFuzzer targets of this directory and runs each for a bounded time on its corpus.
#
#   fuzz/run.sh [seconds per target, default 60] [target ...]   (targets: gmsh vtu vtk_legacy surface)
#
# Environment: BUILD_DIR (default build-fuzz/ at the repository root, ignored by git), CXX
# (default clang++-14, else clang++), FUZZ_FLAGS (more libFuzzer options, e.g. -use_value_profile=1).
# Each target starts from the committed seeds in fuzz/corpus/<target>/ plus the working corpus
# $BUILD_DIR/corpus/<target>/, where new inputs that grow coverage go (`fuzz/run.sh --merge`
# minimises the committed seeds instead of fuzzing). Crashes, leaks and timeouts are written to
# $BUILD_DIR/findings/<target>/ and make the script exit non-zero; once fixed, a finding belongs in
# tests/data/fuzz_regressions/ (see fuzz/README.md).
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
build=${BUILD_DIR:-$root/build-fuzz}
cxx=${CXX:-$(command -v clang++-14 || command -v clang++ || echo clang++)}
all_targets=(gmsh vtu vtk_legacy surface)

merge=0
if [[ ${1:-} == --merge ]]; then
  merge=1
  shift
fi
seconds=${1:-60}
shift || true
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=("${all_targets[@]}")

mkdir -p "$build"
# -fno-sanitize-recover: a UBSan report stops the run like an ASan one, so libFuzzer keeps the input.
flags=(-std=c++20 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
       -I "$root/include" -I/usr/include/eigen3)
# Builds and fuzzing runs go JOBS at a time (default: the number of cores), each run still
# getting its full time: on 2 cores the three readers take two rounds, not three.
jobs=${JOBS:-$(nproc)}
running=0
status=0
# reap: waits for one background job; a failed one sets status. throttle: reaps one once
# `jobs` are running; drain: reaps them all.
reap() {
  wait -n || status=1
  running=$((running - 1))
}
throttle() { if (( running >= jobs )); then reap; fi; }
drain() { while (( running > 0 )); do reap; done; }

for t in "${targets[@]}"; do
  src=$here/fuzz_$t.cpp
  bin=$build/fuzz_$t
  [[ -f $src ]] || { echo "no such target: $t (have: ${all_targets[*]})" >&2; exit 2; }
  # Rebuild when the target or a header it reads (mesh/, element/, core/, embedding/) is newer than the binary.
  inc=$root/include/plastifem
  if [[ ! -x $bin || -n $(find "$src" "$here/fuzz_common.hpp" "$inc/mesh" "$inc/element" "$inc/core" "$inc/embedding" -newer "$bin" \
                          -print -quit) ]]; then
    throttle
    echo "building $bin"
    "$cxx" "${flags[@]}" "$src" -o "$bin" -lfmt &
    running=$((running + 1))
  fi
done
drain
(( status == 0 )) || { echo "building a fuzz target failed" >&2; exit 1; }

# One target's fuzzing run; its summary is printed when it ends.
fuzz_one() {
  local t=$1 seeds=$here/corpus/$1 corpus=$build/corpus/$1 findings=$build/findings/$1
  local log
  log=$build/fuzz_$t.$(date +%Y%m%d-%H%M%S).log
  mkdir -p "$findings"
  echo "fuzzing $t for $seconds s (log: $log)"
  # -timeout: an input that takes over 10 s is a hang; -rss_limit_mb: so is one that takes > 2 GB.
  # New inputs go to the first directory, the working corpus; the seeds are only read.
  if ! "$build/fuzz_$t" "$corpus" "$seeds" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=16384 \
       -dict="$here/$t.dict" -print_final_stats=1 ${FUZZ_FLAGS:-} \
       -artifact_prefix="$findings/" >"$log" 2>&1; then
    echo "  $t FOUND something: see $log and $findings/" >&2
    return 1
  fi
  grep -E "stat::number_of_executed_units|Done [0-9]+ runs" "$log" | tail -2 | sed "s/^/  $t: /" || true
}

for t in "${targets[@]}"; do
  seeds=$here/corpus/$t  # committed, small
  corpus=$build/corpus/$t  # grows with every run, not committed
  mkdir -p "$seeds" "$corpus"
  if [[ $merge == 1 ]]; then  # shrink the committed seeds to those that add coverage
    tmp=$(mktemp -d)
    "$build/fuzz_$t" -merge=1 "$tmp" "$seeds" 2>"$build/merge_$t.log"
    rm -f "$seeds"/*
    cp "$tmp"/* "$seeds"/
    rm -rf "$tmp"
    echo "$t: seed corpus merged to $(ls "$seeds" | wc -l) files"
    continue
  fi
  throttle
  fuzz_one "$t" &
  running=$((running + 1))
done
drain
exit $status
