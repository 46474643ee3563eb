#!/bin/bash
# ThreadSanitizer run of CGAL's parallel Delaunay insertion as tetfsi uses it
# (mesh::Delaunay::build(points, true), `fluid.mesh.parallel_insertion`): builds
# scripts/tsan/delaunay_parallel.cpp with mesh/delaunay.cpp, core/parallel.cpp and core/log.cpp
# under -fsanitize=thread, runs it on N random points (default 20000; ~5 min) and prints
# ThreadSanitizer's report counts by the pair of places, then the program's own check (the
# parallel builds against the sequential one).
# Usage: bash scripts/tsan/run.sh [N]   (from the project root; ~1 min to compile)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
out=${TMPDIR:-/tmp}/tetfsi_tsan
mkdir -p "$out"
g++ -std=c++20 -O1 -g -fsanitize=thread -DCGAL_LINKED_WITH_TBB -DSPDLOG_FMT_EXTERNAL \
  -I"$root" -I/usr/include/eigen3 "$root/scripts/tsan/delaunay_parallel.cpp" \
  "$root/mesh/delaunay.cpp" "$root/core/parallel.cpp" "$root/core/log.cpp" \
  -o "$out/tsan_delaunay" -ltbb -ltbbmalloc -lgmp -lmpfr -lspdlog -lfmt -lpthread
status=0
TSAN_OPTIONS="exitcode=0 ${TSAN_OPTIONS:-}" "$out/tsan_delaunay" "${1:-20000}" >"$out/report.txt" 2>&1 || status=$?
grep -c "WARNING: ThreadSanitizer" "$out/report.txt" | sed 's/^/ThreadSanitizer reports: /' || true
tail -1 "$out/report.txt"
echo "full report: $out/report.txt"
exit $status
