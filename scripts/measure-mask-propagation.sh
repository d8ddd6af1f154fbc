#!/usr/bin/env bash
# Measures one-mask propagation and one-click selection (`instainpaint masks`) against true masks
# in every view: synthetic rooms (exact masks and depth) with each depth source, the network's
# depth carved to the object (--carve on), and one click where a user would click (the pixel
# deepest inside the reference view's mask, scripts/click-inside.py); ../shared/data/statue and,
# with --spinnerf, SPIn-NeRF scene 1 (a mask in every view) alike. Prints a markdown table of
# per-view recall and precision (mean and worst over the views other than the marked one; a
# click's over all views), then the removal quality on the rooms' test views (eval, masked PSNR)
# with the true masks and with each way of making them from the reference view, same reference.
#
#   scripts/measure-mask-propagation.sh [--bin build/instainpaint] [--rooms 6] [--seed 11]
#       [--out mask-propagation] [--checkpoint FILE] [--spinnerf SCENE1 --spinnerf-view 20220819_104351]
set -euo pipefail
BIN=build/instainpaint ROOMS=6 SEED=11 OUT=mask-propagation CHECKPOINT="" SPINNERF="" SPINNERF_VIEW=20220819_104351
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --rooms) ROOMS=$2; shift 2 ;;
    --seed) SEED=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --checkpoint) CHECKPOINT=$2; shift 2 ;;
    --spinnerf) SPINNERF=$2; shift 2 ;;
    --spinnerf-view) SPINNERF_VIEW=$2; shift 2 ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
SHARED=${INSTAINPAINT_SHARED:-$(dirname "$0")/../../shared}
CLICK_INSIDE="python3 $(dirname "$0")/click-inside.py"
MODEL=()
[ -n "$CHECKPOINT" ] && MODEL=(--checkpoint "$CHECKPOINT")
mkdir -p "$OUT"

# One `masks` run; its agreement goes to $OUT/results.tsv as: label, source, mean/worst recall,
# mean/worst precision.
measure() {  # label source out masks-args...
  local label=$1 source=$2 dir=$3
  shift 3
  "$BIN" masks "$@" --out "$dir" > "$dir.log" 2>&1 || { echo "failed: see $dir.log" >&2; exit 1; }
  python3 - "$dir/masks.json" "$label" "$source" >> "$OUT/results.tsv" <<'PY'
import json, sys
a = json.load(open(sys.argv[1]))["agreement"]
print("\t".join([sys.argv[2], sys.argv[3]] + ["%.3f" % a[k] for k in
      ("mean_recall", "worst_recall", "mean_precision", "worst_precision")]))
PY
}

: > "$OUT/results.tsv"
"$BIN" synth --out "$OUT/rooms" --scenes "$ROOMS" --seed "$SEED" --views 12 --test-views 2 --width 256 \
  --height 256 --object procedural --degrade none > "$OUT/synth.log" 2>&1
for scene in "$OUT"/rooms/scene_*; do
  name=$(basename "$scene")
  ref=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["reference"])' "$scene/synth.json")
  mask="$scene/images_4/label/$ref.png"
  measure "$name" "depth file (exact)" "$OUT/$name-file" --scene "$scene" --view "$ref" --mask "$mask" \
    --depth "$scene/depth/$ref.npy"
  measure "$name" "network" "$OUT/$name-network" --scene "$scene" --view "$ref" --mask "$mask" --height 256 "${MODEL[@]}"
  measure "$name" "network, carved" "$OUT/$name-carved" --scene "$scene" --view "$ref" --mask "$mask" --carve on \
    --height 256 "${MODEL[@]}"
  click=$($CLICK_INSIDE "$mask")
  measure "$name" "one click" "$OUT/$name-click" --scene "$scene" --view "$ref" --click "$click" --height 256 "${MODEL[@]}"
  context=$(python3 -c 'import json,sys; print(",".join(json.load(open(sys.argv[1]))["context"]))' "$scene/synth.json")
  for masks in true propagated carved click; do
    extra=()
    case $masks in
      propagated) extra=(--view "$ref" --mask "$mask") ;;
      carved) extra=(--view "$ref" --mask "$mask" --carve on) ;;
      click) extra=(--view "$ref" --click "$click") ;;
    esac
    "$BIN" eval --scene "$scene" --reference "$scene/reference.png" --context "$context" --height 256 \
      "${MODEL[@]}" "${extra[@]}" --out "$OUT/$name-eval-$masks" > "$OUT/$name-eval-$masks.log" 2>&1 ||
      { echo "failed: see $OUT/$name-eval-$masks.log" >&2; exit 1; }
  done
done
# A real capture: the network's depth, carved, and one click.
real_scene() {  # label scene-dir view mask images-args...
  local label=$1 scene=$2 view=$3 mask=$4
  shift 4
  measure "$label" network "$OUT/$label-network" --scene "$scene" "$@" --view "$view" --mask "$mask" "${MODEL[@]}"
  measure "$label" "network, carved" "$OUT/$label-carved" --scene "$scene" "$@" --view "$view" --mask "$mask" \
    --carve on "${MODEL[@]}"
  measure "$label" "one click" "$OUT/$label-click" --scene "$scene" "$@" --view "$view" \
    --click "$($CLICK_INSIDE "$mask")" "${MODEL[@]}"
}
if [ -d "$SHARED/data/statue" ]; then
  real_scene statue "$SHARED/data/statue" IMG_2707 "$SHARED/data/statue/images_2/label/IMG_2707.png"
fi
if [ -n "$SPINNERF" ]; then
  real_scene "spinnerf-1" "$SPINNERF" "$SPINNERF_VIEW" "$SPINNERF/images_4/label/$SPINNERF_VIEW.png" --images images_4
fi

python3 - "$OUT/results.tsv" <<'PY'
import sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1]) if l.strip()]
print("| scene | depth | recall mean | recall worst | precision mean | precision worst |")
print("|---|---|---|---|---|---|")
for r in rows:
    print("| " + " | ".join(r) + " |")
for source in sorted({r[1] for r in rows}):
    for group, sel in (("rooms", lambda r: r[0].startswith("scene_")),):
        sub = [r for r in rows if r[1] == source and sel(r)]
        if not sub:
            continue
        mean = lambda i: sum(float(r[i]) for r in sub) / len(sub)
        worst = lambda i: min(float(r[i]) for r in sub)
        print(f"| **{group} ({len(sub)})** | {source} | {mean(2):.3f} | {worst(3):.3f} | {mean(4):.3f} | {worst(5):.3f} |")
PY

echo
python3 - "$OUT" <<'PY'
import glob, json, os, sys
kinds = ("propagated", "carved", "click")
print("| room | masked PSNR, true masks | " + " | ".join(f"{k} (difference)" for k in kinds) + " |")
print("|---|---|" + "---|" * len(kinds))
diffs = {k: [] for k in kinds}
for true_dir in sorted(glob.glob(os.path.join(sys.argv[1], "scene_*-eval-true"))):
    name = os.path.basename(true_dir)[: -len("-eval-true")]
    t = json.load(open(os.path.join(true_dir, "metrics.json")))["mean"]["masked_psnr"]
    cells = []
    for k in kinds:
        p = json.load(open(os.path.join(sys.argv[1], f"{name}-eval-{k}", "metrics.json")))["mean"]["masked_psnr"]
        diffs[k].append(p - t)
        cells.append(f"{p:.2f} ({p - t:+.2f})")
    print(f"| {name} | {t:.2f} | " + " | ".join(cells) + " |")
if diffs["click"]:
    print("| **mean difference** | | " + " | ".join(f"{sum(d) / len(d):+.2f} dB" for d in diffs.values()) + " |")
PY
