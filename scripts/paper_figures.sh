#!/usr/bin/env bash
# The paper's figures [Chentanez06, Figs. 1-6] as tetfsi pictures them: each scene run with the
# renderer export (output.export), a short sequence of its frames drawn by `tetfsi render` laid
# side by side (scripts/montage.py) into docs/figures/<fig>.png, and, when Blender is installed,
# one frame of the exported files rendered by Blender (scripts/blender_check.py, Cycles on the
# CPU) into docs/figures/<fig>_blender.png. About 20 min on 2 cores; `make figures` runs it.
#   FIGS="fig1 fig3"     only these figures (default: all six)
#   RENDER_ONLY=1        draw the runs already in out/figures/
#   BUILD=build          the build folder
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
tetfsi="$BUILD/cli/tetfsi"
[[ -x $tetfsi ]] || { echo "paper_figures: $tetfsi not built; run make build" >&2; exit 1; }
mkdir -p docs/figures out/figures
FIGS=${FIGS:-fig1 fig2 fig3 fig4 fig5 fig6}
SIZE=${SIZE:-480x270}

wanted() { [[ " $FIGS " == *" $1 "* ]]; }

# run NAME SCENE STEPS EVERY EXPORT [--set ...]: the run into out/figures/NAME (kept going on a
# failed run: its frames up to the failure are what the figure shows).
run() {
  local name=$1 scene=$2 steps=$3 every=$4 export=$5
  shift 5
  local out="out/figures/$name"
  if [[ ${RENDER_ONLY:-0} == 1 && -f $out/summary.json ]]; then return 0; fi
  echo "paper_figures: $name: $scene, $steps steps -> $out"
  "$tetfsi" run "data/scenes/$scene.json" --out "$out" --steps "$steps" --progress off \
    --set "output.every=$every" --set "output.export=$export" "$@" >/dev/null ||
    echo "paper_figures: $name stopped early (see $out/summary.json)"
}

# strip FIG NAME "STEPS" [render options]: `tetfsi render` of those steps, side by side.
strip() {
  local fig=$1 name=$2 steps=$3
  shift 3
  local pngs=() out="out/figures/$name"
  mkdir -p "$out/pictures"
  for s in $steps; do
    local png="$out/pictures/strip_$s.png"
    if "$tetfsi" render "$out" --step "$s" --size "$SIZE" -o "$png" "$@" >/dev/null 2>&1; then
      pngs+=("$png")
    fi
  done
  ((${#pngs[@]})) || { echo "paper_figures: $name has none of the steps $steps" >&2; return 1; }
  /usr/bin/python3 scripts/montage.py "${pngs[@]}" -o "docs/figures/$fig.png"
}

# blender FIG NAME: the last exported frame rendered by Blender (skipped without Blender).
blender_frame() {
  local fig=$1 name=$2
  command -v blender >/dev/null || { echo "paper_figures: no blender, ${fig}_blender skipped"; return 0; }
  blender -b --factory-startup -noaudio --python-exit-code 2 -P scripts/blender_check.py -- \
    "out/figures/$name" --frame last --png "docs/figures/${fig}_blender.png" --size "$SIZE" \
    --samples 32 >"out/figures/$name/blender.log" 2>&1 ||
    { echo "paper_figures: blender on $name failed: $(tail -1 "out/figures/$name/blender.log")" >&2; return 1; }
  rm -f "docs/figures/${fig}_blender_nosmoke.png"  # the check's picture without the smoke
  echo "paper_figures: docs/figures/${fig}_blender.png"
}

# Fig. 1: the jet of smoke through the rubber sheets, t = 0.5, 1, 1.5, 2 s.
if wanted fig1; then
  run smoke_sheets smoke_sheets 100 25 '["vdb","ply"]'
  strip fig1_smoke_sheets smoke_sheets "25 50 75 100"
  blender_frame fig1_smoke_sheets smoke_sheets
fi
# Fig. 2: the liquid-filled toy bouncing off the floor, cut open (a slice through its middle
# coloured by the speed of the liquid inside, the shell see-through), t = 0.25 ... 1 s.
if wanted fig2; then
  run toy toy 120 30 '["ply"]'
  strip fig2_toy toy "30 60 90 120" --slice y=0.5 --color velocity --body-opacity 0.35 --zoom 1.8
  blender_frame fig2_toy toy
fi
# Fig. 3: the paddle blown by the jet, rotating and bouncing on the floor, t = 0.5 ... 2 s.
if wanted fig3; then
  run paddle paddle 100 25 '["vdb","ply"]'
  strip fig3_paddle paddle "25 50 75 100"
  blender_frame fig3_paddle paddle
fi
# Fig. 4: paint poured over the bunny, t = 0.1 ... 0.4 s.
if wanted fig4; then
  run bunny bunny 200 50 '["vdb","ply"]'
  strip fig4_bunny bunny "50 100 150 200"
  blender_frame fig4_bunny bunny
fi
# Fig. 5: the bowl of liquid falling into the shallow tank, t = 0.05 ... 0.2 s.
if wanted fig5; then
  run bowl bowl 100 25 '["vdb","ply"]'
  strip fig5_bowl bowl "25 50 75 100"
  blender_frame fig5_bowl bowl
fi
# four steps evenly spaced over the frames a run wrote (a run that diverged: up to its last)
spread() {
  /usr/bin/python3 -c 'import json, sys
f = json.load(open(sys.argv[1]))["frames"]
s = [x["step"] for x in f][1:]
print(" ".join(str(s[round(i * (len(s) - 1) / 3)]) for i in range(4)) if s else "")' \
    "out/figures/$1/export.json"
}

# Fig. 6: the bar in water: simultaneous at h = 1/30 s, splitting at 1/30 s and at 1/120 s
# (both go unstable here: the bar is lighter than its added mass, docs/results/coupling.md),
# four frames of each up to t = 2 s or the divergence; one strip per run, stacked.
if wanted fig6; then
  run bar_simultaneous bar 60 15 '["ply"]'
  run bar_splitting bar 60 1 '["ply"]' --set coupling.scheme=splitting
  run bar_splitting_120 bar 240 1 '["ply"]' --set coupling.scheme=splitting \
    --set time.dt=0.008333333333333333
  strip fig6_a bar_simultaneous "$(spread bar_simultaneous)"
  strip fig6_b bar_splitting "$(spread bar_splitting)"
  strip fig6_c bar_splitting_120 "$(spread bar_splitting_120)"
  /usr/bin/python3 scripts/montage.py docs/figures/fig6_{a,b,c}.png --cols 1 \
    -o docs/figures/fig6_bar.png
  rm -f docs/figures/fig6_[abc].png
fi
ls -l docs/figures/
