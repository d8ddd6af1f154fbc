#!/usr/bin/env bash
# The region an object leaves, measured where the truth is known: masked PSNR / SSIM of the
# object-free test views, feed-forward and refined (each of --settings: a --refine value), next to
# classical 2D inpainting of each test view on its own (OpenCV Telea, from that view's own
# surroundings: no 3D consistency).
#
#   rooms:  the model card's evaluation rooms (synth --seed 9000, never used in training), 256²,
#           12 input views, 4 object-free test views, each room's context and exact reference;
#   real:   SPIn-NeRF scenes given with --real DIR[:REFERENCE[:CONTEXT]] (repeatable): the scene's
#           60 photos with masks and 40 object-free photos, at 512 rows, with the official
#           learned 2D-inpainted reference and context views when given.
# Each run's metrics.json and report.html stay in OUT/<scene>-<setting>; OUT/results.tsv holds
# the table, OUT/<scene>-regions.png three held-out views (rows) as the truth, 2D Telea and each
# setting show them (columns; the region outlined in red).
#
#   scripts/measure-region.sh [--bin build/instainpaint] [--out region] [--rooms 4]
#       [--real DIR[:REFERENCE[:CONTEXT]]]... [--settings "0 balanced"] [--checkpoint FILE]
set -euo pipefail
BIN=build/instainpaint OUT=region ROOMS=4 REAL=() SETTINGS="0 balanced" MODEL=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --rooms) ROOMS=$2; shift 2 ;;
    --real) REAL+=("$2"); shift 2 ;;
    --settings) SETTINGS=$2; shift 2 ;;
    --checkpoint) MODEL=(--checkpoint "$2"); shift 2 ;;
    -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$OUT"
printf 'scene\tsetting\tpsnr\tssim\tmasked_psnr\tmasked_ssim\tseconds\n' > "$OUT/results.tsv"
metric() { python3 -c 'import json,sys; m=json.load(open(sys.argv[1]))["mean"]; print(m.get(sys.argv[2], "nan"))' "$@"; }
record() {  # scene setting folder seconds
  local m="$3/metrics.json"
  printf '%s\t%s\t%.2f\t%.4f\t%.2f\t%.4f\t%s\n' "$1" "$2" "$(metric "$m" psnr)" "$(metric "$m" ssim)" \
    "$(metric "$m" masked_psnr)" "$(metric "$m" masked_ssim)" "$4" | tee -a "$OUT/results.tsv"
}

run_scene() {  # name scene height reference context
  local name=$1 scene=$2 height=$3 reference=$4 context=$5
  local common=(--scene "$scene" --height "$height")
  [ -n "$reference" ] && common+=(--reference "$reference")
  [ -n "$context" ] && common+=(--context "$context")
  for method in telea; do
    "$BIN" eval "${common[@]}" --method "$method" --out "$OUT/$name-$method" > "$OUT/$name-$method.log" 2>&1
    record "$name" "2D $method" "$OUT/$name-$method" 0
  done
  for setting in $SETTINGS; do
    local start=$(date +%s)
    "$BIN" eval "${common[@]}" "${MODEL[@]}" --refine "$setting" --out "$OUT/$name-$setting" > "$OUT/$name-$setting.log" 2>&1
    record "$name" "refine $setting" "$OUT/$name-$setting" $(($(date +%s) - start))
  done
}

for k in $(seq 0 $((ROOMS - 1))); do
  rooms="$OUT/rooms"
  [ -d "$rooms/scene_$(printf %03d "$k")" ] || "$BIN" synth --out "$rooms" --scenes "$ROOMS" --seed 9000 --views 12 \
    --test-views 4 --width 256 --height 256 --object procedural --degrade none > "$OUT/synth.log" 2>&1
  scene="$rooms/scene_$(printf %03d "$k")"
  context=$(python3 -c 'import json,sys; print(",".join(json.load(open(sys.argv[1]))["context"]))' "$scene/synth.json")
  run_scene "room$k" "$scene" 256 "$scene/reference.png" "$context"
done
for spec in "${REAL[@]}"; do
  IFS=: read -r scene reference context <<< "$spec"
  run_scene "$(basename "$scene")" "$scene" 512 "$reference" "$context"
done

# Three held-out views per scene: the truth, then each run's render with the region outlined (the
# first and last panels of eval's per-view sheets).
for log in "$OUT"/*-telea.log; do
  name=$(basename "$log" -telea.log)
  runs=("$OUT/$name-telea")
  for setting in $SETTINGS; do runs+=("$OUT/$name-$setting"); done
  mapfile -t sheets < <(ls "${runs[0]}/sheets" | awk 'NR==1{a=$0} {b[NR]=$0} END{print a; print b[int((NR+1)/2)]; print b[NR]}')
  inputs=() filter="" row=0
  for sheet in "${sheets[@]}"; do
    col=0
    for run in "${runs[@]}"; do
      inputs+=(-i "$run/sheets/$sheet")
      [ $col -eq 0 ] && filter+="[$((row * ${#runs[@]}))]crop=iw/4:ih:0:0[t$row];"
      filter+="[$((row * ${#runs[@]} + col))]crop=iw/4:ih:3*iw/4:0[c${row}_$col];"
      col=$((col + 1))
    done
    filter+="[t$row]$(for c in $(seq 0 $((${#runs[@]} - 1))); do printf '[c%s_%s]' $row $c; done)hstack=$((${#runs[@]} + 1))[r$row];"
    row=$((row + 1))
  done
  ffmpeg -loglevel error -y "${inputs[@]}" -filter_complex "${filter}[r0][r1][r2]vstack=3" "$OUT/$name-regions.png"
  echo "wrote $OUT/$name-regions.png (columns: truth, 2D telea, refine: $SETTINGS)"
done
