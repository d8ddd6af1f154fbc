#!/usr/bin/env bash
# Filling the hole in splat scenes with exact ground truth: synthetic rooms, each
# written as the splat scene a fit to its training views could hold (synth --save-gaussians:
# scene.ply, the object in it, the floor under it never seen), the object's box removed and
# the hole filled, the held-out views compared inside the object's mask with the room without it.
#
# Rows per room: deletion alone (fill --delete-only), fill, fill + --refine fast, and the photo
# pipeline on the same room (eval --refine fast: the network on the photos, refined). Prints a
# Markdown table of the masked PSNR / SSIM (means over the test views) and the fills' times.
#
# Usage: scripts/measure-fill.sh [--bin build/instainpaint] [--rooms 3] [--seed 11] [--work DIR]
#        [--refine fast] [--placement surface|network] [--inpainter telea|ns|patch] [--no-refine]
# (--no-refine: deletion and fill alone, the refined columns left empty.)
set -euo pipefail
BIN=build/instainpaint
ROOMS=3
SEED=11
WORK=measure-fill
REFINE=fast
PLACEMENT=surface
INPAINTER=telea
NO_REFINE=0
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --rooms) ROOMS=$2; shift 2 ;;
    --seed) SEED=$2; shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    --refine) REFINE=$2; shift 2 ;;
    --placement) PLACEMENT=$2; shift 2 ;;
    --inpainter) INPAINTER=$2; shift 2 ;;
    --no-refine) NO_REFINE=1; shift ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
mkdir -p "$WORK"
here=$(cd "$(dirname "$0")" && pwd)
say() { echo "measure-fill: $*" >&2; }

say "synthetic rooms (seed $SEED) with their splat scenes"
[ -d "$WORK/rooms/scene_000" ] || "$BIN" synth --out "$WORK/rooms" --scenes "$ROOMS" --seed "$SEED" --views 24 \
  --test-views 8 --object procedural --save-gaussians --no-depth > "$WORK/synth.log" 2>&1

metric() {  # metric FILE KEY: the mean of KEY in an eval's metrics.json
  python3 -c "import json,sys; v=json.load(open(sys.argv[1]))['mean'].get(sys.argv[2]); print('%.2f' % v if isinstance(v, float) and sys.argv[2].endswith('psnr') else '%.3f' % v if isinstance(v, float) else v)" "$1" "$2"
}
seconds() {  # seconds FILE: a fill.json's total
  python3 -c "import json,sys; print('%.1f' % (json.load(open(sys.argv[1]))['total_ms'] / 1000))" "$1"
}

echo "| room | splats | removed | deletion only | fill | fill + refine $REFINE | photo pipeline (eval --refine $REFINE) | fill time, with refine |"
echo "|---|---|---|---|---|---|---|---|"
for room in "$WORK"/rooms/scene_*; do
  name=$(basename "$room")
  out="$WORK/$name"
  mkdir -p "$out"
  box=$(python3 "$here/splat-bounds.py" "$room/object.ply" --grow 1.1)
  common=(--scene "$room" --box "$box" --height 256 --device cpu)
  say "$name: box $box"
  "$BIN" fill "$room/scene.ply" "${common[@]}" --delete-only --out "$out/deleted.ply" > "$out/deleted.log" 2>&1
  "$BIN" fill "$room/scene.ply" "${common[@]}" --placement "$PLACEMENT" --inpainter "$INPAINTER" --out "$out/filled.ply" > "$out/filled.log" 2>&1
  methods=(deleted filled)
  if [ "$NO_REFINE" = 0 ]; then
    "$BIN" fill "$room/scene.ply" "${common[@]}" --placement "$PLACEMENT" --inpainter "$INPAINTER" --refine "$REFINE" --out "$out/refined.ply" \
      > "$out/refined.log" 2>&1
    methods+=(refined)
  fi
  for method in "${methods[@]}"; do
    "$BIN" eval --scene "$room" --gaussians "$out/$method.ply" --height 256 --device cpu --no-report \
      --out "$out/eval-$method" > "$out/eval-$method.log" 2>&1
  done
  if [ "$NO_REFINE" = 0 ]; then
    "$BIN" eval --scene "$room" --height 256 --device cpu --no-report --refine "$REFINE" --out "$out/eval-photos" \
      > "$out/eval-photos.log" 2>&1
    methods+=(photos)
  fi
  cells=()
  for method in "${methods[@]}"; do
    m="$out/eval-$method/metrics.json"
    cells+=("$(metric "$m" masked_psnr) dB / $(metric "$m" masked_ssim)")
  done
  [ "$NO_REFINE" = 0 ] || cells+=("–" "–")
  splats=$(python3 -c "import json; print(json.load(open('$out/filled-fill/fill.json'))['splats']['input'])")
  removed=$(python3 -c "import json; print(json.load(open('$out/filled-fill/fill.json'))['splats']['removed'])")
  echo "| $name | $splats | $removed | ${cells[0]} | ${cells[1]} | ${cells[2]} | ${cells[3]} | $(seconds "$out/filled-fill/fill.json") s$([ "$NO_REFINE" = 1 ] || echo ", $(seconds "$out/refined-fill/fill.json") s") |"
done
