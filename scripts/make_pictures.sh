#!/usr/bin/env bash
# Regenerate the README's pictures docs/smoke_sheets.png, docs/paddle.png and docs/toy.png:
# run each scene for part of its length into out/pictures/<scene>/ and render its last frame
# with `tetfsi render` (960 x 540). `make pictures` runs this after building. About 8 min on 2
# cores (smoke_sheets 100 steps ~3.5 min, paddle 50 steps ~2 min, toy 45 steps ~1.5 min).
#   STEPS_SMOKE_SHEETS=.. STEPS_PADDLE=.. STEPS_TOY=..   override the step counts
#   BUILD=build                                         the build folder
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
tetfsi="$BUILD/tools/tetfsi"
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
  echo "make_pictures: $scene, $steps steps -> $out"
  "$tetfsi" run "data/scenes/$scene.json" --out "$out" --steps "$steps" --progress plain \
    "${run_opts[@]}" >/dev/null
  "$tetfsi" render "$out" --size 960x540 -o "docs/$scene.png" "${render_opts[@]}"
}

# The jet has bent sheet_a and is deflected onto sheet_b (t = 2 s; a frame every step, so that
# `tetfsi render out/pictures/smoke_sheets --all` times 101 frames).
picture smoke_sheets "${STEPS_SMOKE_SHEETS:-100}" --set output.every=1
# The paddle, pushed by the jet, tips over towards the floor (t = 1 s).
picture paddle "${STEPS_PADDLE:-50}"
# The toy after landing (t = 0.75 s): a vertical slice through it, the shell see-through, the
# pressure of the water inside.
picture toy "${STEPS_TOY:-45}" -- --slice y=0.5 --body-opacity 0.35
ls -l docs/*.png
