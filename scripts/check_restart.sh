#!/usr/bin/env bash
# Restart equals continuation, bit for bit, on the scenes of issue 19's "must show" list.
# For each scene: run 2N steps straight; then run it again and stop after N steps in each of
# the ways a user stops a run, resume to 2N, and compare with the straight run
# with compare_runs.py (every VTU/VTP/VTI array and every non-timing stats.csv column but the
# remesh's path, which a resume resets to a full rebuild, bit for bit; scripts/compare_runs.py,
# or $COMPARE_RUNS):
#   steps    run --steps N, then resume --steps 2N (the run is extended)
#   sigterm  SIGTERM at a random step k in 1..N (after stats.csv has k rows)
#   stopfile a file OUT/STOP at a random step
#   sigkill  SIGKILL at a random step of a run checkpointing every step (a kill may land in a
#            checkpoint write: the previous checkpoint must be the one resumed from)
# Prints one line per case, "SAME" or "DIFF" (with compare_runs.py's summary), and exits 1 if
# any differs. Usage:
#   scripts/check_restart.sh [-n N] [-b BUILD_DIR] [-k] [SCENE_CASE ...]
# SCENE_CASE: smoke_sheets toy bar_splitting shell_step smoke_jet (default: all); -k keeps the
# work folder (printed). One thread (OMP_THREAD_LIMIT=1, as ctest runs).
set -uo pipefail
cd "$(dirname "$0")/.."
n=3
build=build
keep=0
while getopts "n:b:k" opt; do
  case $opt in
    n) n=$OPTARG ;;
    b) build=$OPTARG ;;
    k) keep=1 ;;
    *) exit 2 ;;
  esac
done
shift $((OPTIND - 1))
tetfsi="$PWD/$build/cli/tetfsi"
# compare_runs.py: $COMPARE_RUNS, else scripts/compare_runs.py.
compare=${COMPARE_RUNS:-scripts/compare_runs.py}
[ -x "$tetfsi" ] || { echo "error: no $tetfsi: build first (make build)" >&2; exit 2; }
[ -f "$compare" ] || { echo "error: no $compare" >&2; exit 2; }
export OMP_THREAD_LIMIT=1 OMP_NUM_THREADS=1

# The scenes, with the settings that make them small enough (coarse fluid meshes).
declare -A args=(
  [smoke_sheets]="data/scenes/smoke_sheets.json --set fluid.mesh.surface_size=0.06 --set fluid.mesh.far_size=0.2"
  [toy]="data/scenes/toy.json"
  [bar_splitting]="data/scenes/bar.json --set coupling.scheme=splitting"
  [shell_step]="data/scenes/shell_step.json --set solid.reform=run"
  [smoke_jet]="data/scenes/smoke_jet.json"
)
cases=("$@")
[ ${#cases[@]} -eq 0 ] && cases=(smoke_sheets toy bar_splitting shell_step smoke_jet)

work=$(mktemp -d /tmp/check_restart.XXXXXX)
[ $keep -eq 1 ] && echo "work folder: $work"
status=0
total=$((2 * n))

# run_stopped OUT ACTION ROWS RUN_ARGS...: start a run, wait until its stats.csv has ROWS
# rows, do ACTION ("TERM", "KILL" or "STOP"), wait for it; prints the exit code.
run_stopped() {
  local out=$1 action=$2 rows=$3
  shift 3
  "$tetfsi" "$@" --out "$out" --progress off >"$out.log" 2>&1 &
  local p=$!
  while [ "$(cat "$out/stats.csv" 2>/dev/null | wc -l)" -le "$rows" ]; do
    kill -0 $p 2>/dev/null || break
    sleep 0.05
  done
  case $action in
    TERM) kill -TERM $p 2>/dev/null ;;
    KILL) kill -KILL $p 2>/dev/null ;;
    STOP) touch "$out/STOP" ;;
  esac
  wait $p
  echo $?
}

report() {  # report CASE HOW OUT EXTRA
  local verdict
  verdict=$(/usr/bin/python3 "$compare" --ignore remesh_incremental,vertices_removed,vertices_inserted "$work/$1/straight" "$3" 2>&1 | tail -1)
  if [[ $verdict == SAME* ]]; then
    printf '%-14s %-9s SAME   %s%s\n' "$1" "$2" "$verdict" "$4"
  else
    printf '%-14s %-9s DIFF   %s%s\n' "$1" "$2" "$verdict" "$4"
    status=1
  fi
}

for c in "${cases[@]}"; do
  [ -n "${args[$c]:-}" ] || { echo "error: unknown case '$c'" >&2; exit 2; }
  read -r -a scene <<<"${args[$c]}"
  d="$work/$c"
  mkdir -p "$d"
  if ! "$tetfsi" run "${scene[@]}" --steps $total --out "$d/straight" --progress off >"$d/straight.log" 2>&1; then
    echo "$c: the straight run failed: $(tail -1 "$d/straight.log")"
    status=1
    continue
  fi
  # by --steps
  "$tetfsi" run "${scene[@]}" --steps $n --out "$d/steps" --checkpoint-every $n --progress off >"$d/steps.log" 2>&1
  "$tetfsi" resume "$d/steps" --steps $total --progress off >>"$d/steps.log" 2>&1
  report "$c" steps "$d/steps" " (stopped after $n)"
  # by SIGTERM, by a STOP file, by SIGKILL: at a random step in 1..N
  for how in sigterm stopfile sigkill; do
    k=$((1 + RANDOM % n))
    extra=()
    case $how in
      sigterm) action=TERM ;;
      stopfile) action=STOP ;;
      sigkill) action=KILL extra=(--checkpoint-every 1) k=$((k + 1)) ;;  # step 1's checkpoint exists
    esac
    code=$(run_stopped "$d/$how" $action $k run "${scene[@]}" --steps $total "${extra[@]}")
    stopped=$(($(wc -l <"$d/$how/stats.csv") - 1))
    tmp=$(cd "$d/$how/checkpoints" 2>/dev/null && ls -- *.tmp 2>/dev/null)
    "$tetfsi" resume "$d/$how" --progress off >>"$d/$how.log" 2>&1
    from=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1])).get("resumed_from_step"))' "$d/$how/summary.json")
    report "$c" $how "$d/$how" " (exit code $code after step $stopped of $total; resumed from step $from${tmp:+; killed while writing $tmp})"
  done
done
[ $keep -eq 1 ] || rm -rf "$work"
exit $status
