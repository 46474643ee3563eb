#!/usr/bin/env bash
# Regenerate the manual's pictures docs/smoke_sheets.png, docs/paddle.png, docs/toy.png,
# docs/dam_break.png, docs/bunny.png and docs/bowl.png
# (and docs/smoke_sheets_stats.png, `tetfsi plot` of the smoke_sheets run):
# run each scene for part of its length into out/pictures/<scene>/ and render its last frame
# with `tetfsi render` (960 x 540). `make pictures` runs this after building. About 12 min on 2
# cores (smoke_sheets 100 steps ~3.5 min, paddle 100 steps ~2.5 min, toy 90 steps ~1 min,
# bunny 150 steps ~1 min, bowl 100 steps ~2.5 min).
#   STEPS_SMOKE_SHEETS=.. STEPS_PADDLE=.. STEPS_TOY=.. STEPS_DAM_BREAK=..
#   STEPS_BUNNY=.. STEPS_BOWL=..                         override the step counts
#   RENDER_ONLY=1                                       render the runs already in out/pictures
#   BUILD=build                                         the build folder
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
tetfsi="$BUILD/cli/tetfsi"
[[ -x $tetfsi ]] || { echo "make_pictures: $tetfsi not built; run make build" >&2; exit 1; }
mkdir -p docs

picture() {  # scene steps [run options] -- [render options]
  local scene=$1 steps=$2
  shift 2
  local run_opts=() render_opts=()
  while (($#)) && [[ $1 != -- ]]; do run_opts+=("$1"); shift; done
  (($#)) && shift
  render_opts=("$@")
  local out="out/pictures/$scene"
  if [[ ${RENDER_ONLY:-0} != 1 || ! -f $out/summary.json ]]; then
    echo "make_pictures: $scene, $steps steps -> $out"
    "$tetfsi" run "data/scenes/$scene.json" --out "$out" --steps "$steps" --progress plain \
      "${run_opts[@]}" >/dev/null
  fi
  "$tetfsi" render "$out" --size 960x540 -o "docs/$scene.png" "${render_opts[@]}"
}

# The jet has bent sheet_a and is deflected onto sheet_b (t = 2 s; a frame every step, so that
# `tetfsi render out/pictures/smoke_sheets --all` times 101 frames).
picture smoke_sheets "${STEPS_SMOKE_SHEETS:-100}" --set output.every=1
# The paddle pushed by the jet (t = 2 s, its whole run).
picture paddle "${STEPS_PADDLE:-100}"
# The toy after landing (t = 0.75 s at the scene's dt of 1/120 s). A vertical slice through
# it, the shell see-through, zoomed on the toy: the pressure of the water inside.
picture toy "${STEPS_TOY:-90}" -- --slice y=0.5 --body-opacity 0.35 --zoom 1.8
# The dam break's surge climbing the far wall (t = 0.32 s; ~20 s): the liquid's surface.
picture dam_break "${STEPS_DAM_BREAK:-160}"
# The stream pouring over the bunny's back (t = 0.3 s; the bunny's colour: von Mises stress).
picture bunny "${STEPS_BUNNY:-150}"
# The bowl just after hitting the tank's floor, its liquid squirting out (t = 0.2 s).
picture bowl "${STEPS_BOWL:-100}"
# smoke_sheets' stats.csv as plots (tetfsi plot).
"$tetfsi" plot out/pictures/smoke_sheets -o docs/smoke_sheets_stats.png
ls -l docs/*.png
