#!/usr/bin/env bash
# How long `instainpaint fill` takes on a large splat scene (the target: 1 M Gaussians filled
# without refinement in 10 s or less on a 2-core CPU): a synthetic room written at 512 x 512 with
# dense Gaussians (synth --detail), its splat scene (scene.ply) filled with the object's box at
# the default working height; prints the whole command's wall time and its stage table.
#
# Usage: scripts/measure-fill-speed.sh [--bin build/instainpaint] [--detail 1.3] [--work DIR]
#        [--device cpu] [--runs 3] [--placement surface|network]
set -euo pipefail
BIN=build/instainpaint
DETAIL=1.3
WORK=measure-fill-speed
DEVICE=cpu
RUNS=3
PLACEMENT=surface
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --detail) DETAIL=$2; shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    --device) DEVICE=$2; shift 2 ;;
    --runs) RUNS=$2; shift 2 ;;
    --placement) PLACEMENT=$2; shift 2 ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$WORK"
room="$WORK/rooms/scene_000"
[ -f "$room/scene.ply" ] || "$BIN" synth --out "$WORK/rooms" --scenes 1 --seed 11 --views 24 --test-views 2 \
  --width 512 --height 512 --detail "$DETAIL" --object procedural --save-gaussians --no-depth > "$WORK/synth.log" 2>&1
box=$(python3 "$here/splat-bounds.py" "$room/object.ply" --grow 1.1)
for run in $(seq "$RUNS"); do
  start=$(date +%s.%N)
  "$BIN" fill "$room/scene.ply" --scene "$room" --box "$box" --device "$DEVICE" --placement "$PLACEMENT" --out "$WORK/filled.ply" \
    > "$WORK/fill.log" 2>&1
  end=$(date +%s.%N)
  echo "run $run: $(python3 -c "print('%.2f' % ($end - $start))") s, the whole command ($(tail -1 "$WORK/fill.log"))"
done
python3 "$here/stage-table.py" "$WORK/filled-fill/fill.json" --title "fill, last run"
