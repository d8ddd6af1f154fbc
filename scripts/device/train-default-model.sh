#!/usr/bin/env bash
# Run ON a lent GPU machine: trains a candidate default model (preset `medium`, 256 x 256, bf16)
# in one device call, from the binary that build-and-check.sh bundled (no build here). The recipe
# is scripts/train-default-model.sh's (synthetic rooms plus real scenes, stage 1 reconstruction,
# stage 2 inpainting with the depth loss), scaled to a GPU. The statue scene is left out: it is
# the real scene the model is judged on. Evaluation happens afterwards on any machine
# (models/MODEL_CARD.md); this writes to $OUT:
#   stage1.safetensors, model.safetensors   the models after each stage (the latter updated at
#                                           every checkpoint, so a run cut short still returns one)
#   train.log                               everything printed
# Here, before:   scripts/device/prepare.sh; copy the bundle from build-and-check.sh's $OUT to
#                 .device/bundle/instainpaint.tar.xz
#   run(command="bash scripts/device/train-default-model.sh", carry=[".device/bundle", ".device/scenes"])
# Environment: STAGE1_STEPS, STAGE2_STEPS, BATCH, ROOMS (training rooms), WORKERS.
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${OUT:-$PWD/device-out}
STAGE1_STEPS=${STAGE1_STEPS:-1500}
STAGE2_STEPS=${STAGE2_STEPS:-2000}
BATCH=${BATCH:-8}
ROOMS=${ROOMS:-96}
WORKERS=${WORKERS:-12}
WORK=/tmp/ii-train
mkdir -p "$OUT" "$WORK"
exec > >(tee -a "$OUT/train.log") 2>&1
step() { printf '\n== %s (%s)\n' "$*" "$(date +%T)"; }

source scripts/device/deps.sh
device_deps_from_bundle
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader || true
"$BIN" --version

step "training rooms ($ROOMS, seed 1001) and validation rooms (6, seed 777001) at 256 x 256"
"$BIN" synth --out "$WORK/train" --scenes "$ROOMS" --seed 1001 --views 20 --test-views 4 --width 256 --height 256 \
  --degrade mixed --threads "$(nproc)" 2>&1 | tail -1
"$BIN" synth --out "$WORK/val" --scenes 6 --seed 777001 --views 20 --test-views 4 --width 256 --height 256 \
  --degrade mixed --threads "$(nproc)" 2>&1 | tail -1
SCENES="$WORK/train,.device/scenes/fern,.device/scenes/fox"
common=(--scenes "$SCENES" --val-scenes "$WORK/val" --width 256 --height 256 --inputs 4 --targets 4
  --batch "$BATCH" --device cuda --precision bf16 --workers "$WORKERS" --val-every 250 --val-samples 12
  --save-every 250 --log-every 50)

step "stage 1: reconstruction, $STAGE1_STEPS steps"
"$BIN" train "${common[@]}" --out "$WORK/stage1" --stage reconstruct --preset medium --steps "$STAGE1_STEPS" \
  --lr 6e-4 --warmup 100
cp "$WORK/stage1/model.safetensors" "$OUT/stage1.safetensors"

step "stage 2: masked inpainting with the depth loss, $STAGE2_STEPS steps"
# The last checkpoint goes to $OUT while training runs: a call cut short still brings a model back.
( while sleep 20; do
    [ -f "$WORK/stage2/model.safetensors" ] && cp "$WORK/stage2/model.safetensors" "$OUT/model.safetensors.part" &&
      mv "$OUT/model.safetensors.part" "$OUT/model.safetensors"
  done ) &
copier=$!
"$BIN" train "${common[@]}" --out "$WORK/stage2" --stage inpaint --init "$WORK/stage1/model.safetensors" \
  --steps "$STAGE2_STEPS" --lr 4e-4 --warmup 100 --depth-weight 0.2
kill "$copier"
cp "$WORK/stage2/model.safetensors" "$OUT/model.safetensors"
cp "$WORK/stage1/log.jsonl" "$OUT/stage1-log.jsonl"
cp "$WORK/stage2/log.jsonl" "$OUT/stage2-log.jsonl"
step "done"
