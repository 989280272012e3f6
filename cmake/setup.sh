#!/usr/bin/env bash
# plastifem set-up: installs missing Debian packages, configures, builds, then runs
#   bash cmake/setup.sh example   the flagship example (writes VTU/PVD into build/out/)
#   bash cmake/setup.sh test      the whole test suite through ctest
#   bash cmake/setup.sh bench [step|static|policy] [options]
#                                 a benchmark (tables + CSV into build/bench/): ms per Newmark
#                                 step (default), per static solve, or the NoPlasticity /
#                                 NoEnrichment overhead ratio
#   bash cmake/setup.sh study     the accuracy-vs-cost study (docs/study.md): CSV into build/bench/,
#                                 plot into docs/speed_accuracy.png (~7 min, single-threaded)
# Environment: BUILD_DIR (default build), JOBS (default: number of cores).
set -euo pipefail
cd "$(dirname "$0")/.."
what=${1:-test}
build=${BUILD_DIR:-build}
jobs=${JOBS:-$(nproc)}

# libsuitesparse-dev: CHOLMOD, the sparse direct solver for statics (optional for users of the
# library, used by default here); libopenblas0-pthread: the BLAS its supernodes run on (12x
# faster than the reference BLAS on bar5760 statics).
packages=(g++ cmake make pkg-config libeigen3-dev libfmt-dev catch2 libsuitesparse-dev libopenblas0-pthread)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release
case "$what" in
  example)
    cmake --build "$build" -j "$jobs" --target cantilever
    mkdir -p "$build/out"
    "$build/examples/cantilever" --out "$build/out" ;;
  test)
    cmake --build "$build" -j "$jobs"
    ctest --test-dir "$build" --output-on-failure -j "$jobs" ;;
  bench)
    which=step; args=("${@:2}")
    case "${2:-}" in step|static|policy) which=$2; args=("${@:3}") ;; esac
    target=bench_$which; [ "$which" = policy ] && target=bench_policy_overhead
    cmake --build "$build" -j "$jobs" --target "$target"
    mkdir -p "$build/bench"
    "$build/bench/$target" --csv "$build/bench/$which.csv" "${args[@]}" ;;
  study)
    cmake --build "$build" -j "$jobs" --target study_accuracy
    mkdir -p "$build/bench"
    # One core throughout: the study's costs are single-threaded, CHOLMOD's BLAS included.
    OPENBLAS_NUM_THREADS=1 "$build/bench/study_accuracy" --csv "$build/bench/study_accuracy.csv" "${@:2}"
    if ! /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
      echo "setup: installing python3-matplotlib"
      sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
      $sudo apt-get update -qq
      DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends python3-matplotlib
    fi
    /usr/bin/python3 docs/plot_study.py "$build/bench/study_accuracy.csv" docs/speed_accuracy.png ;;
  *) echo "usage: bash cmake/setup.sh example|test|bench|study" >&2; exit 2 ;;
esac
