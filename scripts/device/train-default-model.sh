#!/usr/bin/env bash
# Run ON a lent GPU machine: trains a candidate default model (preset `medium`, bf16) in one
# device call (the program alone is built first, about 2 minutes on 16 cores). The recipe
# is scripts/train-default-model.sh's (synthetic rooms plus real scenes, stage 1 reconstruction,
# stage 2 inpainting with the depth loss), scaled to a GPU. The statue scene is left out: it is
# the real scene the model is judged on. Evaluation happens afterwards on any machine
# (models/MODEL_CARD.md); this writes to $OUT:
#   model.part-aa, -ab, ...   the model (the stage-2 checkpoint, updated while training runs, so a run
#                             cut short still returns one), in pieces under the tool's 16 MiB a file:
#                             cat model.part-* > model.safetensors
#   train.log                 everything printed; stage1-log.jsonl, stage2-log.jsonl the runs' logs
# Here, before: scripts/device/prepare.sh. Run 2026-11-25 at 128 x 128 (see docs/benchmarks.md, "Training"):
#   run(command="SIZE=128 BATCH=16 STAGE_SECONDS=185 bash scripts/device/train-default-model.sh",
#       carry=[".device/debs", ".device/scenes"])
# Environment: SIZE (pixels, square), STAGE1_STEPS, STAGE2_STEPS, BATCH, ROOMS (training rooms),
# WORKERS, STAGE_SECONDS (each stage is stopped after this long; its last checkpoint counts).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${OUT:-$PWD/device-out}
SIZE=${SIZE:-256}
STAGE_SECONDS=${STAGE_SECONDS:-3600}
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
device_deps_from_debs
device_build_program_and_rooms "$OUT" "$WORK" "$ROOMS" "$SIZE"
SCENES="$WORK/train,.device/scenes/fern,.device/scenes/fox"
common=(--scenes "$SCENES" --val-scenes "$WORK/val" --width "$SIZE" --height "$SIZE" --inputs 4 --targets 4
  --batch "$BATCH" --device cuda --precision bf16 --workers "$WORKERS" --val-every 250 --val-samples 12
  --save-every 100 --log-every 50)

step "stage 1: reconstruction, $STAGE1_STEPS steps"
timeout "$STAGE_SECONDS" "$BIN" train "${common[@]}" --out "$WORK/stage1" --stage reconstruct --preset medium --steps "$STAGE1_STEPS" \
  --lr 6e-4 --warmup 100 || echo "stage 1 stopped early (status $?)"

step "stage 2: masked inpainting with the depth loss, $STAGE2_STEPS steps"
# The last checkpoint goes to $OUT while training runs: a call cut short still brings a model back.
export_model() { rm -f "$OUT"/model.part-*; split -b 15M "$WORK/stage2/model.safetensors" "$OUT/model.part-"; }
( while sleep 20; do [ -f "$WORK/stage2/model.safetensors" ] && export_model; done ) &
copier=$!
timeout "$STAGE_SECONDS" "$BIN" train "${common[@]}" --out "$WORK/stage2" --stage inpaint --init "$WORK/stage1/model.safetensors" \
  --steps "$STAGE2_STEPS" --lr 4e-4 --warmup 100 --depth-weight 0.2 || echo "stage 2 stopped early (status $?)"
kill "$copier"
export_model
cp "$WORK/stage1/log.jsonl" "$OUT/stage1-log.jsonl"
cp "$WORK/stage2/log.jsonl" "$OUT/stage2-log.jsonl"
step "done"
