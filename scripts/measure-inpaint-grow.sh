#!/usr/bin/env bash
# How far the region the 2D inpainter paints is grown past the object's mask (--inpaint-grow),
# measured in 3D with object-free truth: the model card's evaluation rooms (synth --seed 9000,
# 4 at 256², their own context, the reference painted by --inpainter from its mask, no given
# reference), and any SPIn-NeRF-layout scene given with --scene (its object-free test views;
# SPIn-NeRF scene 1 as in docs/editing.md). One eval per scene and growth; prints the region's
# (masked) and the whole image's PSNR per growth, and the mean over the rooms. With --box GROW,
# the rooms' masks are not their exact labels but what a user's box makes: the reference view
# marked by its label's box grown by GROW (--view --box: GrabCut, lifted and carved), whose edges
# hold the object's rim as real selections do. Needs the Python package (make python: .venv-py)
# for --box.
#
#   scripts/measure-inpaint-grow.sh [--grows "0 0.01 0.02 0.04"] [--inpainter ns] [--rooms 4]
#       [--box 0.05] [--scene DIR ...] [--height 256] [--bin build/instainpaint] [--out inpaint-grow]
set -euo pipefail
BIN=build/instainpaint OUT=inpaint-grow GROWS="0 0.01 0.02 0.04" INPAINTER=ns ROOMS=4 HEIGHT=256 BOX=""
SCENES=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --grows) GROWS=$2; shift 2 ;;
    --inpainter) INPAINTER=$2; shift 2 ;;
    --rooms) ROOMS=$2; shift 2 ;;
    --scene) SCENES+=("$2"); shift 2 ;;
    --height) HEIGHT=$2; shift 2 ;;
    --box) BOX=$2; shift 2 ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$OUT"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores; $(git rev-parse --short HEAD); $(date -u +%F)"
printf 'scene\tgrow\tmasked_psnr\tpsnr\n' > "$OUT/results.tsv"

# evaluate <scene dir> <grow> <eval args...>: one row of results.tsv.
evaluate() {
  local scene=$1 grow=$2
  shift 2
  local dir="$OUT/$(basename "$scene")-$grow"
  "$BIN" eval --scene "$scene" --out "$dir" --no-report --height "$HEIGHT" --inpainter "$INPAINTER" \
    --inpaint-grow "$grow" "$@" > "$dir.log" 2>&1 || { echo "failed: see $dir.log" >&2; exit 1; }
  python3 - "$dir/metrics.json" "$(basename "$scene")" "$grow" >> "$OUT/results.tsv" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))["mean"]
print(f"{sys.argv[2]}\t{sys.argv[3]}\t{m['masked_psnr']:.2f}\t{m['psnr']:.2f}")
PY
  tail -1 "$OUT/results.tsv"
}

if [ "$ROOMS" -gt 0 ]; then
  "$BIN" synth --out "$OUT/rooms" --scenes "$ROOMS" --seed 9000 --views 12 --test-views 4 --width 256 --height 256 \
    --degrade none > "$OUT/synth.log" 2>&1
  for room in "$OUT/rooms"/scene_*; do
    context=$(python3 -c "import json, sys; print(','.join(json.load(open(sys.argv[1]))['context']))" "$room/synth.json")
    marked=()
    if [ -n "$BOX" ]; then
      reference=${context%%,*}
      box=$(PYTHONPATH="$(dirname "$0")" .venv-py/bin/python -c "
import sys, instainpaint as ii
from importlib import import_module
grown_box = import_module('measure-click-every-view').grown_box
print(','.join(f'{v:g}' for v in grown_box(ii.load_scene(sys.argv[1]).mask(sys.argv[2]), float(sys.argv[3]))))" \
        "$room" "$reference" "$BOX")
      marked=(--view "$reference" --box "$box")
    fi
    for grow in $GROWS; do evaluate "$room" "$grow" --context "$context" "${marked[@]}"; done
  done
fi
for scene in "${SCENES[@]}"; do
  for grow in $GROWS; do evaluate "$scene" "$grow"; done
done
python3 - "$OUT/results.tsv" <<'PY'
import collections, sys
rows = [line.rstrip("\n").split("\t") for line in open(sys.argv[1])][1:]
rooms = collections.defaultdict(list)
for scene, grow, masked, whole in rows:
    if scene.startswith("scene_"):
        rooms[grow].append((float(masked), float(whole)))
for grow, values in rooms.items():
    print(f"rooms' mean, grow {grow}: region {sum(v[0] for v in values) / len(values):.2f} dB, "
          f"whole {sum(v[1] for v in values) / len(values):.2f} dB ({len(values)} rooms)")
PY
