#!/usr/bin/env bash
# plastifem set-up: installs missing Debian packages, configures, builds, then runs
#   bash cmake/setup.sh example   the flagship example (writes VTU/PVD into build/out/)
#   bash cmake/setup.sh scenes    the five surgical scenes, each to its end (build/out/SCENE/)
#   bash cmake/setup.sh live [options]  the live demo: builds and starts its server, prints the
#                                 address to open (examples/live/README.md; installs three.js
#                                 with npm)
#   bash cmake/setup.sh live-test the live demo's browser test (Debian's Chromium, headless), its
#                                 scenes test and its malformed-input test
#   bash cmake/setup.sh test      the test suite through ctest, without the cases tagged [long]
#                                 (builds the tests only: ~20 min on 2 cores from scratch)
#   bash cmake/setup.sh test-long the cases tagged [long] (long runs, fine meshes)
#   bash cmake/setup.sh sanitize  a representative subset of the tests (every element, model and
#                                 reader) built with AddressSanitizer + UndefinedBehaviorSanitizer
#                                 into build-sanitize/
#   bash cmake/setup.sh fuzz [s]  the mesh and surface readers' libFuzzer targets, s seconds each (default 60;
#                                 installs clang; fuzz/README.md)
#   bash cmake/setup.sh build-time  what including the toolkit costs the compiler
#                                 (docs/build_time.md): CPU seconds and peak memory per translation unit
#   bash cmake/setup.sh bench [step|static|policy|io|scenes|organ] [options]
#                                 a benchmark (tables + CSV into build/bench/): ms per Newmark
#                                 step (default), per static solve, or the NoPlasticity /
#                                 NoEnrichment overhead ratio, or per VTU write and read, or the
#                                 surgical scenes' step and event times (bench/scenes.sh), or
#                                 steps on unstructured Tet4 liver meshes (organ [levels, default
#                                 3,4,5] [bench_step options]; installs gmsh, which meshes them)
#   bash cmake/setup.sh study     the accuracy-vs-cost study (docs/study.md): CSV into build/bench/,
#                                 plot into docs/speed_accuracy.png (~7 min, single-threaded)
# Environment: BUILD_DIR (default build, or build-sanitize), JOBS (default: number of cores).
set -euo pipefail
cd "$(dirname "$0")/.."
what=${1:-test}
build=${BUILD_DIR:-build}
[ "$what" = sanitize ] && build=${BUILD_DIR:-build-sanitize}
jobs=${JOBS:-$(nproc)}

# apt-get install of whatever in "$@" is missing.
install_missing() {
  local missing=() p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    local sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
}

# libsuitesparse-dev: CHOLMOD, the sparse direct solver for statics (optional for users of the
# library, used by default here); libopenblas0-pthread: the BLAS its supernodes run on (12x
# faster than the reference BLAS on bar5760 statics).
packages=(g++ cmake make pkg-config libeigen3-dev libfmt-dev catch2 libsuitesparse-dev libopenblas0-pthread)
# The live demo's server (examples/live, built in the project's own builds): HTTP and JSON.
packages+=(libcpp-httplib-dev nlohmann-json3-dev)
install_missing "${packages[@]}"

# The live demo's page and test: node and npm (Debian's, unless a node is there already), then
# three.js and puppeteer-core as pinned in examples/live/package-lock.json.
live_npm() {
  command -v npm > /dev/null || install_missing nodejs npm
  if [ ! -f examples/live/node_modules/.package-lock.json ] ||
     [ examples/live/package-lock.json -nt examples/live/node_modules/.package-lock.json ]; then
    (cd examples/live && npm ci --no-audit --no-fund)
  fi
}

# The sanitizer build: the test subset that instantiates every element (test_elements), every
# elastic model on every element (test_point_law, test_state), every reader and writer (test_io,
# fuzz regressions included), the mesh checks, assembly, linear solvers, the solver's steps,
# grasping and the bad-input regressions. -O1 keeps it quick; Debug leaves Eigen's own
# assertions on (index checks); -g1 (line tables: a report's stack still names file and line)
# builds in 7.6 min on 2 cores where full -g took 12 (its type information for every Eigen
# expression is most of the compiler's memory); any report stops the test. UndefinedBehaviorSanitizer
# runs without its null and alignment checks, which put a test before nearly every reference and
# member access of the Eigen code and cost a third of the build (solver_tet4.cpp: 96 -> 66 s;
# AddressSanitizer alone 56 s): a null access still stops the test as AddressSanitizer's SEGV
# report, Eigen's Debug assertions check its fixed-size types' alignment, and the readers, the
# one place bytes become numbers (by memcpy), are fuzzed with every -fsanitize=undefined check.
sanitize_tests=(test_elements test_mesh test_io test_assembly test_linear_solver test_point_law
                test_state test_solver test_grasp test_defects)
if [ "$what" = sanitize ]; then
  san="-O1 -g1 -fsanitize=address,undefined -fno-sanitize=null,alignment -fno-sanitize-recover=all -fno-omit-frame-pointer"
  targets=()
  for t in "${sanitize_tests[@]}"; do [ -f "tests/$t.cpp" ] && targets+=("$t"); done
  # PLASTIFEM_TEST_ONLY: only these tests exist in this build, and plastifem_tests builds them
  # in parallel (several --target names are built one after another).
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="$san" \
        -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
        -DPLASTIFEM_BUILD_EXAMPLES=OFF -DPLASTIFEM_BUILD_BENCH=OFF -DPLASTIFEM_COMPILED_POLICIES=OFF \
        -DPLASTIFEM_TEST_ONLY="$(IFS=';'; echo "${targets[*]}")"
  cmake --build "$build" -j "$jobs" --target plastifem_tests
  regex="^($(IFS='|'; echo "${targets[*]}")):"
  # Every target must register cases: a name pattern that matches nothing would make this stage
  # pass without running anything (it once ran 3 of its 124 cases).
  for t in "${targets[@]}"; do
    count=$(ctest --test-dir "$build" -N -LE long -R "^$t:" | sed -n 's/^Total Tests: //p')
    [ "${count:-0}" -gt 0 ] || { echo "sanitize: no test cases registered for $t"; exit 1; }
  done
  # halt_on_error: the first report fails the test; leaks are reported too.
  ASAN_OPTIONS=halt_on_error=1:detect_leaks=1:strict_string_checks=1 \
  UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
    ctest --test-dir "$build" --output-on-failure -j "$jobs" -R "$regex" -LE long
  exit 0
fi

# PLASTIFEM_TEST_ONLY= : every test, whatever an earlier configure of this directory asked for.
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DPLASTIFEM_BUILD_LIVE=ON -DPLASTIFEM_TEST_ONLY=
case "$what" in
  live)  # the live demo: bash cmake/setup.sh live [--port N] [--scene organ|fat|sheet] ...
    cmake --build "$build" -j "$jobs" --target live
    live_npm
    exec "$build/examples/live/live" --out "$build/out/live" "${@:2}" ;;
  live-test)  # the live demo in headless Chromium, and against malformed commands
    install_missing chromium
    cmake --build "$build" -j "$jobs" --target live
    live_npm
    mkdir -p "$build/out"
    bin=$(cd "$build" && pwd)/examples/live/live shot=$(cd "$build" && pwd)/out/live_demo.png
    (cd examples/live && export LIVE_BIN="$bin" &&
       SHOT="$shot" node test/browser.mjs && node test/scenes.mjs && node test/malformed.mjs) ;;
  example)
    cmake --build "$build" -j "$jobs" --target cantilever
    mkdir -p "$build/out"
    "$build/examples/cantilever" --out "$build/out" ;;
  scenes)  # the five surgical scenes, each run to its end (docs/scenes.md)
    scenes=(fat_grasp vessel_twist liver_cage liver_cut sheet_tear)
    cmake --build "$build" -j "$jobs" --target surgical_scenes
    for scene in "${scenes[@]}"; do
      echo "setup: $scene"
      "$build/examples/$scene" --out "$build/out/$scene" | tail -n 4
    done ;;
  test)
    cmake --build "$build" -j "$jobs" --target plastifem_tests
    ctest --test-dir "$build" --output-on-failure -j "$jobs" -LE long ;;
  test-long)
    cmake --build "$build" -j "$jobs" --target plastifem_tests
    ctest --test-dir "$build" --output-on-failure -j "$jobs" -L long ;;
  all)  # everything builds (tests, examples, benchmarks), warnings as errors
    cmake --build "$build" -j "$jobs" ;;
  fuzz)
    install_missing clang libclang-rt-dev
    bash fuzz/run.sh "${2:-60}" ;;
  build-time)
    bash bench/build_time.sh "$build" ;;
  bench)
    which=step; args=("${@:2}")
    case "${2:-}" in step|static|policy|io) which=$2; args=("${@:3}") ;; esac
    if [ "${2:-}" = scenes ]; then
      cmake --build "$build" -j "$jobs" --target surgical_scenes
      mkdir -p "$build/bench"
      bash bench/scenes.sh "$build" "$build/bench/scenes.csv" "${@:3}"
      exit 0
    fi
    if [ "${2:-}" = organ ]; then
      install_missing gmsh
      cmake --build "$build" -j "$jobs" --target organ_mesh bench_step
      mkdir -p "$build/bench"
      levels=3,4,5; rest=("${@:3}")
      if [[ "${3:-}" =~ ^[0-9]+(,[0-9]+)*$ ]]; then levels=$3; rest=("${@:4}"); fi
      "$build/bench/organ_mesh" --levels "$levels" --out "$build/bench/organ"
      msh=$(for k in ${levels//,/ }; do printf '%s,' "$build/bench/organ/liver$k.msh"; done)
      "$build/bench/bench_step" --scenes "" --msh "${msh%,}" --csv "$build/bench/organ.csv" "${rest[@]}"
      exit 0
    fi
    target=bench_$which; [ "$which" = policy ] && target=bench_policy_overhead
    cmake --build "$build" -j "$jobs" --target "$target"
    mkdir -p "$build/bench"
    "$build/bench/$target" --csv "$build/bench/$which.csv" "${args[@]}" ;;
  study)
    cmake --build "$build" -j "$jobs" --target study_accuracy
    mkdir -p "$build/bench"
    # One core throughout: the study's costs are single-threaded, CHOLMOD's BLAS included.
    OPENBLAS_NUM_THREADS=1 "$build/bench/study_accuracy" --csv "$build/bench/study_accuracy.csv" "${@:2}"
    install_missing python3-matplotlib
    /usr/bin/python3 docs/plot_study.py "$build/bench/study_accuracy.csv" docs/speed_accuracy.png ;;
  *) echo "usage: bash cmake/setup.sh example|scenes|live|live-test|test|test-long|sanitize|fuzz|build-time|all|bench|study" >&2; exit 2 ;;
esac
