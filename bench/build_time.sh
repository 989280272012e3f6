#!/usr/bin/env bash
# What including plastifem costs the compiler: CPU seconds (user + system) and peak memory of
# one translation unit, for what a simulator's files typically contain.
#
#   bash bench/build_time.sh [build dir, default build]     (or: bash cmake/setup.sh build-time)
#
#   umbrella         #include <plastifem/plastifem.hpp> and nothing used
#   solver           one Solver<Hex8, Corotational>: a bar, a fixed end, gravity, a step, a
#                    static solve, header-only (the TU instantiates and optimises everything)
#   solver+compiled  the same file against plastifem::compiled (-DPLASTIFEM_USE_COMPILED and
#                    -DPLASTIFEM_CHECK_FORMATS, as the target carries them: the common Solver
#                    types are extern templates, compiled once in the library)
#   readers          the umbrella plus <plastifem/mesh/io/io.hpp> and one read_gmsh<Hex8>
#
# Memory: "peak MB" is what the compile takes with g++'s default garbage collection; "live MB"
# the same compile collecting at every 10% of growth (--param ggc-min-expand=10 --param
# ggc-min-heapsize=8192): the stable measure for comparing two trees. The default peak also
# depends on where the collections fall, which any header edit moves: one more header of
# function templates the Solver file does not call moved its peak by 18 MB, its live memory by
# 0.1 MB. LIVE_MB=0 skips the second compile (it takes twice the time); "-" for a compiler other
# than g++.
# Flags: CXX (default g++), OPT (default -O2), the include paths of the build's CMake cache
# (Eigen, SuiteSparse) and OpenMP; results as a table and as CSV in <build>/bench/build_time.csv.
set -euo pipefail
shopt -s inherit_errexit  # a failed compile inside $( ) stops the script, not a garbage row
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-build}
cxx=${CXX:-g++}
opt=${OPT:--O2}
live_mb=${LIVE_MB:-1}
"$cxx" -v 2>&1 | grep -q '^gcc version' || live_mb=0  # --param ggc-* is g++'s
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

eigen=/usr/include/eigen3
if [ -f "$build/CMakeCache.txt" ]; then
  d=$(sed -n 's/^Eigen3_DIR:PATH=//p' "$build/CMakeCache.txt")
  [ -n "$d" ] && [ -f "$d/Eigen3Config.cmake" ] && eigen=$(sed -n 's/.*EIGEN3_INCLUDE_DIRS "\([^"]*\)".*/\1/p' "$d/Eigen3Config.cmake" | head -1)
  [ -d "$eigen" ] || eigen=/usr/include/eigen3
fi
flags=(-std=c++20 "$opt" -DNDEBUG -fopenmp -I"$root/include" -isystem "$eigen")

cat >"$work/umbrella.cpp" <<'EOF'
#include <plastifem/plastifem.hpp>
int main() { return 0; }
EOF
cat >"$work/solver.cpp" <<'EOF'
#include <plastifem/plastifem.hpp>
#include <fmt/core.h>
int main() {
  using namespace plastifem;
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(2, 2, 8);
  Solver<Hex8, Corotational> solver(mesh, Material{1e5, 0.3, 1000});
  solver.fix(select_nodes(mesh, [](const Vec3& x) { return x.z() < 1e-9; }));
  solver.add_gravity(Vec3(0, -9.81, 0));
  const StepReport r = solver.step(0.01);
  solver.solve_static();
  fmt::print("{} {}\n", r.newton_iterations, solver.displacement().norm());
}
EOF
cat >"$work/readers.cpp" <<'EOF'
#include <plastifem/plastifem.hpp>
#include <plastifem/mesh/io/io.hpp>
int main(int argc, char** argv) {
  if (argc > 1) return static_cast<int>(plastifem::io::read_gmsh<plastifem::Hex8>(argv[1]).num_elements() % 2);
  return 0;
}
EOF

compile() {  # time-format, time-file, extra flags...: one timed compile of unit $name
  local format=$1 out=$2; shift 2
  /usr/bin/time -f "$format" -o "$out" "$cxx" "${flags[@]}" "$@" -c "$work/${name%%+*}.cpp" -o "$work/$name.o" ||
    { echo "build_time.sh: $name failed to compile" >&2; exit 1; }
}

measure() {  # name, extra flags...: prints "name seconds peak-megabytes live-megabytes"
  local name=$1; shift
  compile "%U %S %M" "$work/$name.time" "$@"
  read -r user sys kb <"$work/$name.time"
  local live=""  # the same compile collecting at every 10% of growth (see the top of this file)
  if [ "$live_mb" != 0 ]; then
    compile "%M" "$work/$name.live" "$@" --param ggc-min-expand=10 --param ggc-min-heapsize=8192
    live=$(awk '{ printf "%.0f", $1 / 1024 }' "$work/$name.live")
  fi
  awk -v n="$name" -v u="$user" -v s="$sys" -v k="$kb" -v l="${live:--}" 'BEGIN { printf "%s %.1f %.0f %s\n", n, u + s, k / 1024, l }'
}

results=$( {
  measure umbrella
  measure solver
  measure solver+compiled -DPLASTIFEM_USE_COMPILED -DPLASTIFEM_CHECK_FORMATS
  measure readers
} )
mkdir -p "$build/bench"
{
  echo "unit,cpu_seconds,peak_mb,live_mb"
  echo "$results" | tr ' ' ','
} >"$build/bench/build_time.csv"
echo "$("$cxx" --version | head -1), $opt"
printf '%-18s %12s %10s %10s\n' "translation unit" "CPU seconds" "peak MB" "live MB"
echo "$results" | while read -r n s m l; do printf '%-18s %12s %10s %10s\n' "$n" "$s" "$m" "$l"; done
echo "CSV: $build/bench/build_time.csv"
