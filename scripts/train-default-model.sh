#!/usr/bin/env bash
# How models/default.safetensors was made (see models/MODEL_CARD.md): synthetic rooms plus the
# real scenes of ../shared/data, stage 1 (RGB-only reconstruction) then stage 2 (masked
# inpainting, finally with a depth loss) on the `mini` preset, on 2 CPU cores. Usage:
#   scripts/train-default-model.sh [WORK_DIR]      (default: runs/default-model)
#   CONTINUE=1 scripts/train-default-model.sh [WORK_DIR]   (the 2026-11-27 continuation alone)
# Each stage resumes after an interruption: run the script again.
set -euo pipefail
BIN=${BIN:-build/instainpaint}
SHARED=${SHARED:-../shared}
WORK=${1:-runs/default-model}
STAGE1_STEPS=${STAGE1_STEPS:-2500}
STAGE2_STEPS=${STAGE2_STEPS:-1500}
mkdir -p "$WORK"

# Training rooms (seed 1001) and validation rooms (seed 777001); the evaluation rooms of the
# model card use seed 9000 and are never seen in training.
[ -d "$WORK/train" ] || "$BIN" synth --out "$WORK/train" --scenes 40 --seed 1001 --views 20 --test-views 4 \
  --width 128 --height 128 --degrade mixed
[ -d "$WORK/val" ] || "$BIN" synth --out "$WORK/val" --scenes 6 --seed 777001 --views 20 --test-views 4 \
  --width 128 --height 128 --degrade mixed
SCENES="$WORK/train,$SHARED/data/fern,$SHARED/data/fox,$SHARED/data/statue"

resume() { [ -f "$1/checkpoint.safetensors" ] && echo --resume || true; }

# The last step of the embedded model, alone with CONTINUE=1: stage 2 continued on 2 CPU cores
# at 128 x 128 with six real captures of ../shared/data/realtrain beside the rooms (2026-11-27;
# the LLFF ones: the Strecha scenes need scripts/strecha-to-nerfstudio.py first, and a run with
# them was not adopted, 2026-11-27), from the weights the stages below and 240 steps on an H200 made
# (scripts/device/finetune-default-model.sh, 2026-11-26; INIT, default: the embedded model):
# 1,500 steps, 17 minutes.
if [ "${CONTINUE:-0}" = 1 ]; then
  REAL="$SHARED/data/realtrain"
  MORE="$REAL/dtu_scan24,$REAL/dtu_scan37,$REAL/custom_beer_can,$REAL/custom_office_drinkbox,$REAL/custom_coffee_cup"
  MORE+=",$REAL/custom_milk_carton_whitebg"
  "$BIN" train --scenes "$WORK/train,$SHARED/data/fern,$SHARED/data/statue,$MORE" --val-scenes "$WORK/val" \
    --out "$WORK/real-128" $(resume "$WORK/real-128") --stage inpaint --init "${INIT:-models/default.safetensors}" \
    --width 128 --height 128 --inputs 4 --targets 4 --batch 2 --steps 1500 --lr 1.5e-4 --warmup 50 \
    --depth-weight 0.2 --val-every 500 --val-samples 6 --save-every 250
  cp "$WORK/real-128/model.safetensors" models/default.safetensors
  echo "wrote models/default.safetensors; reconfigure (cmake) and rebuild to embed it"
  exit 0
fi

"$BIN" train --scenes "$SCENES" --val-scenes "$WORK/val" --out "$WORK/stage1" $(resume "$WORK/stage1") \
  --stage reconstruct --preset mini --width 64 --height 64 --inputs 4 --targets 4 --batch 2 \
  --steps "$STAGE1_STEPS" --lr 1e-3 --warmup 100 --val-every 250 --val-samples 6 --save-every 250

"$BIN" train --scenes "$SCENES" --val-scenes "$WORK/val" --out "$WORK/stage2" $(resume "$WORK/stage2") \
  --stage inpaint --init "$WORK/stage1/model.safetensors" --width 64 --height 64 --inputs 4 --targets 4 \
  --batch 2 --steps "$STAGE2_STEPS" --lr 5e-4 --warmup 100 --val-every 250 --val-samples 6 --save-every 250

# Stage 2 continued at the demo's and the evaluation's 128 x 128.
"$BIN" train --scenes "$SCENES" --val-scenes "$WORK/val" --out "$WORK/stage2-128" $(resume "$WORK/stage2-128") \
  --stage inpaint --init "$WORK/stage2/model.safetensors" --width 128 --height 128 --inputs 4 --targets 4 \
  --batch 2 --steps 200 --lr 1.5e-4 --warmup 20 --val-every 0 --save-every 100

# Stage 2 continued with the depth loss on the synthetic rooms' depth maps (train --depth-weight,
# not in the official recipe), back at 64 x 64.
"$BIN" train --scenes "$SCENES" --val-scenes "$WORK/val" --out "$WORK/depth" $(resume "$WORK/depth") \
  --stage inpaint --init "$WORK/stage2-128/model.safetensors" --width 64 --height 64 --inputs 4 --targets 4 \
  --batch 2 --steps 1000 --lr 3e-4 --warmup 50 --depth-weight 0.2 --val-every 250 --val-samples 6 --save-every 250

cp "$WORK/depth/model.safetensors" models/default.safetensors
echo "wrote models/default.safetensors; reconfigure (cmake) and rebuild to embed it"
