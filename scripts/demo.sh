#!/usr/bin/env bash
# The main job of `make demo`: a complete run on a scene made here, with the model built into
# instainpaint (no download, no shared data). Everything goes to demo-out/:
#   1. a small synthetic room with an object, and its exact object-free ground truth;
#   2. masks for every view from ONE mask (the reference view's) and its depth map, compared with
#      the exact ones (and the same with the default model's depth);
#   3. inference from that one mask: the Gaussians of the room without the object, as the network
#      predicts them (gaussians-unrefined.ply) and refined for a minute on all the room's views
#      (gaussians.ply, --refine fast);
#   4. the same model given the object (no masks), to compare with;
#   5. novel views of all three next to the ground truth, and an orbit video;
#   6. metrics against the exact ground truth, next to two 2D baselines.
set -euo pipefail
BIN=${1:-build/instainpaint}
OUT=${DEMO_OUT:-demo-out}
SIZE=${DEMO_SIZE:-128}
start=$(date +%s)
rm -rf "$OUT"
mkdir -p "$OUT"
# The demo runs the model built into the binary and the classical methods, whatever networks
# `instainpaint models get` brought into the cache (docs/models.md): its figures are the documented ones.
export INSTAINPAINT_MODELS_DIR="$OUT/no-models"
unset INSTAINPAINT_SEGMENTER INSTAINPAINT_INPAINTER
step() { printf '\n== %s\n' "$*"; }

# --degrade none: the reference view is the exact object-free image, standing in for a good 2D
# inpainter (--degrade telea would give OpenCV's fill instead).
step "1/6 a synthetic room with an object, and the same room without it (ground truth)"
"$BIN" synth --out "$OUT/data" --scenes 1 --seed 2024 --views 12 --test-views 4 \
  --width "$SIZE" --height "$SIZE" --object procedural --degrade none
SCENE="$OUT/data/scene_000"
# The generator picks four context views (reference first) and records them in synth.json.
CONTEXT=$(sed -n '/"context"/,/]/p' "$SCENE/synth.json" | grep -o '"view_[0-9]*"' | tr -d '"' | paste -sd, -)
REF=${CONTEXT%%,*}
# The user marks the object on the reference view only; every other view's mask is made from it,
# lifted with that view's depth map (the room's own, as a depth camera would give it).
ONE_MASK=(--view "$REF" --mask "$SCENE/images_4/label/$REF.png" --depth "$SCENE/depth/$REF.npy")

step "2/6 masks for every view from the mask of $REF alone, lifted with its depth map"
"$BIN" masks --scene "$SCENE" "${ONE_MASK[@]}" --out "$OUT/masks" | sed 's/^/  /'
echo "  (without --depth the default model's reconstruction gives the depth, scaled to the room's depth maps:"
"$BIN" masks --scene "$SCENE" "${ONE_MASK[@]:0:4}" --height "$SIZE" --out "$OUT/masks-network" 2> /dev/null |
  grep against | sed 's/^/   /'
echo "   the network's depth as it is (--align-depth none), about 1.4 times too far here:"
"$BIN" masks --scene "$SCENE" "${ONE_MASK[@]:0:4}" --height "$SIZE" --align-depth none --out "$OUT/masks-network-raw" \
  2> /dev/null | grep against | sed 's/^/   /; s/$/)/'

# A synthetic room like the model's training rooms: its predicted geometry is right, so the
# positions move at 10x 3DGS's rate instead of the 300x that real captures need.
step "3/6 inference with the default model from that one mask: the room without the object, refined on all 12 views"
"$BIN" infer --scene "$SCENE" --reference "$SCENE/reference.png" --context "$CONTEXT" "${ONE_MASK[@]}" \
  --height "$SIZE" --refine fast --refine-position-rate 10 --keep-unrefined --out "$OUT/inpainted"

step "4/6 the same model given the object (no masks), to compare with"
"$BIN" infer --scene "$SCENE" --context "$CONTEXT" --height "$SIZE" --keep-object --out "$OUT/with-object"

step "5/6 novel views (the scene's held-out test cameras) and an orbit video"
for ply in with-object/gaussians inpainted/gaussians-unrefined inpainted/gaussians; do
  "$BIN" render --ply "$OUT/$ply.ply" --scene "$SCENE" --test-views \
    --no-video --out "$OUT/$ply-novel" > /dev/null
done
# One row per test view: with the object | object removed | refined | ground truth
# (nearest-neighbour x2).
inputs=() rows="" row_labels=""
n=0
for truth in "$SCENE"/images_4/test_*.png; do
  frame=$(printf '%04d.png' "$n")
  inputs+=(-i "$OUT/with-object/gaussians-novel/rgb/$frame" -i "$OUT/inpainted/gaussians-unrefined-novel/rgb/$frame"
    -i "$OUT/inpainted/gaussians-novel/rgb/$frame" -i "$truth")
  rows+="[$((4 * n))][$((4 * n + 1))][$((4 * n + 2))][$((4 * n + 3))]hstack=4[r$n];"
  row_labels+="[r$n]"
  n=$((n + 1))
done
ffmpeg -loglevel error -y "${inputs[@]}" \
  -filter_complex "${rows}${row_labels}vstack=$n,scale=iw*2:ih*2:flags=neighbor" "$OUT/novel-views.png"
"$BIN" render --ply "$OUT/inpainted/gaussians.ply" --scene "$SCENE" --trajectory orbit \
  --frames 60 --width $((2 * SIZE)) --height $((2 * SIZE)) --out "$OUT/orbit" > /dev/null

step "6/6 metrics on the object-free test views: the model, refined, and two 2D baselines"
# Each row says what made it: the model, the geometry its depth was aligned to, the measured surface.
made_by() {  # made_by METRICS.JSON
  python3 -c 'import json,sys; p=json.load(open(sys.argv[1]))["prediction"]
g=p.get("geometry", {}).get("source"); d=p.get("geometry", {}).get("detail", 0)
m=p.get("geometry", {}).get("measured_surface", {}).get("views", [])
aligned="%s, depth aligned to %s%s%s" % (p.get("checkpoint"), g, ", detail %g" % d if d else "",
  ", %d views on their measured surface" % len(m) if m else "")
print((aligned if g not in (None, "off", "none") else "%s, its own depth" % p["checkpoint"]) if "checkpoint" in p else "splats of %s" % p["ply"] if "ply" in p else "2D baseline")' "$1"
}
for method in model model-raw refined telea mean-fill; do
  args=(--method "$method")
  [ "$method" = model ] && args+=("${ONE_MASK[@]}")
  [ "$method" = model-raw ] && args=(--method model "${ONE_MASK[@]}" --align-depth none)
  # The refined Gaussians as infer wrote them (in the scene's normalised frame, as eval renders).
  [ "$method" = refined ] && args=(--method model --gaussians "$OUT/inpainted/gaussians.ply")
  "$BIN" eval --scene "$SCENE" --reference "$SCENE/reference.png" --context "$CONTEXT" --height "$SIZE" \
    "${args[@]}" --out "$OUT/eval-$method" > "$OUT/eval-$method.log" 2>&1
  printf '  %-10s %s  (%s)\n' "$method" "$(grep -m1 '^  PSNR' "$OUT/eval-$method.log" | sed 's/^ *//')" \
    "$(made_by "$OUT/eval-$method/metrics.json")"
done

cat <<TXT

Done in $(($(date +%s) - start)) s. In $OUT/:
  masks/                    a mask per view made from the reference view's mask and depth (masks.json: recall, precision)
  inpainted/gaussians.ply   3D Gaussians of the room without the object (standard 3DGS PLY), refined for a
                            minute (--refine fast); gaussians-unrefined.ply: the network's own prediction
  inpainted/depth/          the predicted depth of each context view
  novel-views.png           novel views, one per row: with the object | object removed | refined | ground truth
  orbit/rgb.mp4             an orbit around the scene, object removed
  eval-model/report.html    per test view: ground truth, render, error map, mask outline
  eval-*/metrics.json       PSNR, SSIM and their masked variants (model; refined: inpainted/gaussians.ply;
                            baselines: OpenCV Telea, mean fill)
(telea and mean-fill fill each test view's mask from that view's own ground truth: 2D, no 3D consistency.)

The same on your own capture: a phone video (or photos) posed by COLMAP, then the object painted
on one view in the browser (or marked in a file, that photo painted out by any 2D inpainter):
  $BIN capture my_video.mp4 --out my_capture
  $BIN serve --scene my_capture
  $BIN infer --scene my_capture --view IMG_0001 --mask object.png --reference my_inpainted_IMG_0001.png --out out/my_capture
  $BIN render --ply out/my_capture/gaussians.ply --scene my_capture --trajectory orbit --out out/video
  $BIN --help    (every command; the released official checkpoint: --checkpoint instainpaint.pth)
TXT
