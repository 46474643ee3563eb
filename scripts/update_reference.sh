#!/usr/bin/env bash
# Regenerate the stored reference figures, tests/reference/<case>.csv, for a change that is
# meant to alter results: builds test_run and tetfsi, runs every case of
# tests/reference/manifest.json with TETFSI_UPDATE_REFERENCE=1 (the cases write their CSVs
# instead of comparing), then shows what changed. Review `git diff tests/reference` and
# commit it with the change. Usage: scripts/update_reference.sh [BUILD_DIR] (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
if [ ! -f "$build/CMakeCache.txt" ]; then
  echo "error: no CMake build in '$build': configure first (make build)" >&2
  exit 1
fi
cmake --build "$build" --target test_run
# OMP_THREAD_LIMIT=1 as ctest sets it (tests/CMakeLists.txt); tetfsi sets the rest.
TETFSI_UPDATE_REFERENCE=1 OMP_THREAD_LIMIT=1 "$build/tests/run/test_run" -tc='reference: *'
git status --short -- tests/reference
