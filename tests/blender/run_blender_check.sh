#!/usr/bin/env bash
# ctest `blender_check` (label blender; `make test-blender`): a short smoke_sheets run exported
# for renderers (output.export vdb + ply), its last frame loaded, checked and rendered by
# Blender headless (scripts/blender_check.py), the picture kept at WORK/smoke_sheets.png.
# Then the whole export loaded as sequences (scripts/blender_load_export.py) into
# WORK/sequences.blend, and the check on a manifest with one wrong vertex count must fail
# with exit code 1: a failed check inside Blender reaches the caller.
# Usage: run_blender_check.sh TETFSI_EXE SOURCE_DIR WORK_DIR
# Exit 77 (ctest SKIP_RETURN_CODE) when Blender is not installed; $BLENDER overrides `blender`.
set -euo pipefail
tetfsi=$1 src=$2 work=$3
blender=${BLENDER:-blender}
if ! command -v "$blender" >/dev/null; then
  echo "blender_check: skipped: no '$blender' on PATH (make test-blender installs Debian's)"
  exit 77
fi
steps=${TETFSI_BLENDER_STEPS:-40}  # t = 0.8 s: the smoke has reached the first sheet

run=$work/run
rm -rf "$run" "$work/bad"
mkdir -p "$work"
SECONDS=0
"$tetfsi" run "$src/data/scenes/smoke_sheets.json" --out "$run" --progress off \
  --steps "$steps" --set output.every=10 --set 'output.export=["vdb","ply"]'
run_s=$SECONDS

check=(--factory-startup -noaudio --python-exit-code 2 -P "$src/scripts/blender_check.py" --)
SECONDS=0
"$blender" -b "${check[@]}" "$run" --frame last --png "$work/smoke_sheets.png" \
  --report "$work/report.json" --blend "$work/smoke_sheets.blend" >"$work/blender.log" 2>&1 || {
  rc=$?
  tail -n 30 "$work/blender.log"
  echo "blender_check: Blender exited with $rc (log: $work/blender.log)"
  exit 1
}
blender_s=$SECONDS
grep '^blender_check:' "$work/blender.log"

# The whole export as sequences (scripts/blender_load_export.py), saved as a .blend.
"$blender" -b --factory-startup -noaudio --python-exit-code 2 \
  -P "$src/scripts/blender_load_export.py" -- "$run" --blend "$work/sequences.blend" \
  >"$work/load.log" 2>&1 || { tail -n 20 "$work/load.log"; echo "blender_load_export failed"; exit 1; }
grep '^blender_load_export:' "$work/load.log"

# A wrong manifest must fail the check (exit code 1, one FAIL line), not pass silently.
mkdir -p "$work/bad"
ln -s "$run/vdb" "$work/bad/vdb"
ln -s "$run/ply" "$work/bad/ply"
"${PYTHON:-python3}" - "$run/export.json" "$work/bad/export.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
mesh = m["frames"][-1]["meshes"][0]
mesh["vertices"] += 1
json.dump(m, open(sys.argv[2], "w"))
PY
rc=0
"$blender" -b "${check[@]}" "$work/bad" --frame last --png "$work/bad/bad.png" \
  >"$work/bad/blender.log" 2>&1 || rc=$?
if [[ $rc -ne 1 ]] || ! tail -n 1 "$work/bad/blender.log" | grep -q '^blender_check: FAIL: .*vertices'; then
  tail -n 5 "$work/bad/blender.log"
  echo "blender_check: a wrong vertex count gave exit code $rc, not 1 with a FAIL line"
  exit 1
fi
echo "blender_check: a wrong vertex count fails as it should: $(tail -n 1 "$work/bad/blender.log")"
echo "blender_check: run ${run_s} s ($steps steps), Blender ${blender_s} s; picture $work/smoke_sheets.png"
